"""The MATLAB port, run on GNU Octave, on the shared vectors: one test per problem.

A missing ``octave`` fails these tests with the Debian package to install (never a skip).
"""

from __future__ import annotations

import shutil

import pytest

from flowtrack_course.polyglot import octave as lang_octave
from flowtrack_course.polyglot.base import ToolchainMissing
from flowtrack_course.ports.vectors import VECTORS_DIR
from ports_helpers import (
    BUILD_DIR,
    assert_every_case_passes,
    failing_cases,
    perturbed_vectors,
    run_port,
    vector_case_ids,
)

pytestmark = pytest.mark.xdist_group("ports-octave")

PROBLEMS = ["kalman_cv2d", "white_noise_q", "projection_jacobian", "variational_scene_flow"]


@pytest.fixture(scope="module")
def octave_results():
    return run_port(lang_octave.run, VECTORS_DIR, BUILD_DIR)


@pytest.mark.parametrize("problem", PROBLEMS)
def test_port_passes_every_vector_case(octave_results, problem):
    assert_every_case_passes(octave_results, problem)


def test_harness_reports_exactly_the_perturbed_cases(octave_results, tmp_path):
    folder, spoilt = perturbed_vectors(tmp_path, PROBLEMS)
    results = lang_octave.run(folder, tmp_path)
    assert failing_cases(results, PROBLEMS) == spoilt
    assert len(results) == sum(len(vector_case_ids(p)) for p in PROBLEMS)


def test_missing_vector_file_fails(octave_results, tmp_path):
    results = lang_octave.run(tmp_path, tmp_path)
    assert {r.problem for r in results} == set(PROBLEMS)
    assert not any(r.passed for r in results)


def test_missing_octave_is_reported_not_skipped(monkeypatch, tmp_path):
    monkeypatch.setattr(shutil, "which", lambda name: None)
    with pytest.raises(ToolchainMissing, match="octave"):
        lang_octave.run(VECTORS_DIR, tmp_path)
