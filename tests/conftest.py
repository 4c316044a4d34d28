"""Shared fixtures. Warnings are errors (pyproject); ray-tracing tests use tiny scenes."""

from __future__ import annotations

import os
import signal

# one BLAS thread, as the CLI sets: the chain's matrices are small and multithreaded BLAS on
# them was measured ~10x slower on a loaded 2-core machine (must precede numpy's import)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest
from hypothesis import HealthCheck, settings

# property-based tests (tests/integration/test_bad_inputs_properties.py): derandomized, so CI
# runs the same examples every time and a failure reproduces; no example database written
settings.register_profile("ci", derandomize=True, database=None, print_blob=True,
                          suppress_health_check=[HealthCheck.too_slow])
# HYPOTHESIS_PROFILE=explore: random examples, for a local search beyond the fixed ones
settings.register_profile("explore", parent=settings.get_profile("ci"), derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

# Ctrl-C as a terminal delivers it: the live-server tests stop their servers with SIGINT to the
# process group. A test session started in the background of a non-interactive shell (`cmd &`
# in a script) inherits SIGINT *ignored*, and so would every server it starts, which then never
# stops on it (each test waits 20 s and kills it). A handler here (reset to the default by exec
# in every child) gives the children the disposition a terminal's Ctrl-C meets.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
