"""The C++ ports (Eigen, PCL) on the shared vectors: one test per language and problem.

The CMake project is built once per session into ``cpp_java_matlab_ports/build/cpp`` (incremental,
so a second run only checks time stamps). A missing compiler or library fails these tests with the
Debian packages to install; they are never skipped. The last test proves the harnesses can fail.
"""

from __future__ import annotations

import pytest

from flowtrack_course.polyglot import cpp as lang_cpp
from flowtrack_course.ports.vectors import VECTORS_DIR
from ports_helpers import (
    BUILD_DIR,
    assert_every_case_passes,
    failing_cases,
    perturbed_vectors,
    run_port,
    vector_case_ids,
)

pytestmark = pytest.mark.xdist_group("ports-cpp")

PROBLEMS = {
    "cpp-eigen": [
        "kalman_cv2d",
        "white_noise_q",
        "projection_jacobian",
        "mahalanobis_assignment",
        "graph_scene_flow",
        "variational_scene_flow",
    ],
    "cpp-pcl": ["rigid_icp"],
}


@pytest.fixture(scope="module")
def cpp_build():
    return run_port(lang_cpp.build, BUILD_DIR)


@pytest.fixture(scope="module")
def cpp_results(cpp_build):
    results = []
    for language in lang_cpp.PORTS:
        results += lang_cpp.run_harness(language, VECTORS_DIR, cpp_build)
    return results


@pytest.mark.parametrize(
    ("language", "problem"), [(lang, prob) for lang, probs in PROBLEMS.items() for prob in probs]
)
def test_port_passes_every_vector_case(cpp_results, language, problem):
    assert_every_case_passes(cpp_results, problem, language)


def test_unit_tests_pass(cpp_build):
    results = lang_cpp.run_unit_tests(cpp_build)
    assert {r.language for r in results} == set(lang_cpp.PORTS)
    failed = [f"{r.language} {r.case_id}: {r.message}" for r in results if not r.passed]
    assert not failed, "\n".join(failed)


def test_harnesses_report_exactly_the_perturbed_cases(cpp_build, tmp_path):
    problems = [p for probs in PROBLEMS.values() for p in probs]
    folder, spoilt = perturbed_vectors(tmp_path, problems)
    results = []
    for language in lang_cpp.PORTS:
        results += lang_cpp.run_harness(language, folder, cpp_build)
    assert failing_cases(results, problems) == spoilt
    assert len(results) == sum(len(vector_case_ids(p)) for p in problems)


def test_missing_vector_file_is_an_error(cpp_build, tmp_path):
    with pytest.raises(RuntimeError, match="missing vector file"):
        lang_cpp.run_harness("cpp-pcl", tmp_path, cpp_build)
