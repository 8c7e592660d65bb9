"""Property-based test of the REST API over its own OpenAPI schema (schemathesis).

Every operation gets a bounded number of generated requests (valid and invalid
bodies, query values and ids), derandomized so a run is repeatable; each answer
must be a documented status with the documented schema and content type, and
never a 5xx. The service runs in process against a scheduler that is not there
(degraded start): accepted cases stay queued, so nothing generated is solved.
``/health`` is left out: its documented 503 is right when no scheduler answers.
"""
from __future__ import annotations

import itertools

import pytest
import schemathesis
from hypothesis import HealthCheck, given, settings
from schemathesis import GenerationMode
from schemathesis.checks import not_a_server_error
from schemathesis.python import asgi
from schemathesis.specs.openapi.checks import (content_type_conformance, response_schema_conformance,
                                               status_code_conformance)

from service.app import create_app
from service.process import free_port
from service.settings import LOOPBACK_NAMES, Settings

#: Generated requests per operation and mode (valid data, then data the schema forbids).
EXAMPLES = 20
CHECKS = [not_a_server_error, status_code_conformance, content_type_conformance, response_schema_conformance]


@pytest.fixture(scope="module")
def api_schema(tmp_path_factory):
    # schemathesis's ASGI client calls the app as http://testserver: a name allowed here only
    settings = Settings(results=tmp_path_factory.mktemp("results"), scheduler=f"tcp://127.0.0.1:{free_port()}",
                        reconcile_interval=3600, max_open_cases=100_000, allowed_hosts=(*LOOPBACK_NAMES, "testserver"))
    schema = schemathesis.openapi.from_asgi("/openapi.json", create_app(settings)).exclude(path="/health")
    try:
        yield schema
    finally:
        asgi.shutdown_lifespans()  # the app's lifespan runs from the first request on


def operations(schema) -> list:
    return [result.ok() for result in schema.get_all_operations()]


@pytest.mark.slow
def test_no_server_error_and_responses_match_the_schema(api_schema):
    ops = operations(api_schema)
    assert len(ops) >= 8
    for operation, mode in itertools.product(ops, GenerationMode):
        @given(case=operation.as_strategy(mode))
        @settings(max_examples=EXAMPLES, derandomize=True, deadline=None, database=None,
                  suppress_health_check=list(HealthCheck))
        def check(case):
            case.call_and_validate(checks=CHECKS)

        check()
