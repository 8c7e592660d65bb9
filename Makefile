# tunnel-contact: `make test` and `make demo` work on a fresh machine.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# gmsh's wheel links against these X/GL libraries even when used headless.
DEB_LIBS := libglu1-mesa libgl1 libxrender1 libxcursor1 libxfixes3 libxext6 libxft2 \
            libfontconfig1 libxinerama1 libx11-6 libgomp1
# the dashboard's browser tests drive Debian's headless Chromium through its driver.
DEB_LIBS += chromium chromium-driver

.PHONY: test demo bench sysdeps venv clean

sysdeps:
	@missing=""; for p in $(DEB_LIBS); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages:$$missing"; \
	  SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq $$missing; \
	fi

$(STAMP): pyproject.toml | sysdeps
	$(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e '.[test]'
	touch $(STAMP)

venv: $(STAMP)

# Two test processes (pytest-xdist): a module whose tests share a module-scoped fixture (a served
# app, a browser) stays on one process (tests/conftest.py groups them). The few tests that compare
# times they measure (marked serial) run afterwards, alone. Both parts run; either failing fails.
TEST_PROCESSES ?= 2

test: $(STAMP)
	@status=0; \
	MPLBACKEND=Agg $(BIN)/python -m pytest -q -n $(TEST_PROCESSES) --dist loadgroup -m "not serial" || status=$$?; \
	MPLBACKEND=Agg $(BIN)/python -m pytest -q -m serial || status=$$?; \
	exit $$status

demo: $(STAMP)
	MPLBACKEND=Agg $(BIN)/python -m service.demo

bench: $(STAMP)
	$(BIN)/python -m bench.solver

clean:
	rm -rf $(VENV) results .pytest_cache
