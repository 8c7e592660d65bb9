# One image for the whole deployment: the dask scheduler, the dask workers and the API.
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1 \
    MPLBACKEND=Agg

# gmsh's wheel links against these X/GL libraries even when used headless.
RUN apt-get update \
 && apt-get install -y --no-install-recommends \
      libglu1-mesa libgl1 libxrender1 libxcursor1 libxfixes3 libxext6 libxft2 \
      libfontconfig1 libxinerama1 libx11-6 libgomp1 \
 && rm -rf /var/lib/apt/lists/*

WORKDIR /src
COPY pyproject.toml README.md ./
COPY solver ./solver
COPY workflows ./workflows
COPY service ./service
COPY bench ./bench
COPY examples ./examples
RUN pip install . && python -c "import gmsh, solver, workflows, service.app"

# Unprivileged user; /results is created here so a fresh named volume inherits its owner.
RUN useradd --create-home --uid 1000 tunnel \
 && mkdir /results && chown tunnel:tunnel /results
USER tunnel
WORKDIR /home/tunnel
VOLUME ["/results"]
EXPOSE 8000 8786

CMD ["tunnel-contact", "serve", "--host", "0.0.0.0", "--port", "8000", "--results", "/results"]
