"""The Java ports (plain arrays, EJML, OpenCV) on the shared vectors: one test per language and problem.

Built with javac and Debian's jars into ``cpp_java_matlab_ports/build/java`` once per module. A
missing JDK, jar or JNI library fails these tests with the Debian packages to install (never a
skip). Also: the JUnit 5 suite, the harness-can-fail test, and checks of the ``lucas_kanade``
vector itself against independent computations.
"""

from __future__ import annotations

import numpy as np
import pytest

from flowtrack_course.polyglot import java as lang_java
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

pytestmark = pytest.mark.xdist_group("ports-java")

PROBLEMS = {
    "java": ["kalman_cv2d", "white_noise_q", "projection_jacobian"],
    "java-ejml": ["kalman_cv2d", "white_noise_q"],
    "java-opencv": ["lucas_kanade"],
}


@pytest.fixture(scope="module")
def java_results():
    return run_port(lang_java.run, VECTORS_DIR, BUILD_DIR)


@pytest.mark.parametrize(
    ("language", "problem"), [(lang, prob) for lang, probs in PROBLEMS.items() for prob in probs]
)
def test_port_passes_every_vector_case(java_results, language, problem):
    assert_every_case_passes(java_results, problem, language)


def test_junit_suite_passes(java_results):
    ok, output = lang_java.run_junit(VECTORS_DIR, BUILD_DIR)
    assert ok, output[-3000:]
    assert "tests failed" in output and " 0 tests failed" in output


def test_harness_reports_exactly_the_perturbed_cases(java_results, tmp_path):
    problems = sorted({p for probs in PROBLEMS.values() for p in probs})
    folder, spoilt = perturbed_vectors(tmp_path, problems)
    results = lang_java.run(folder, tmp_path / "build")
    for language, probs in PROBLEMS.items():
        mine = [r for r in results if r.language == language]
        assert failing_cases(mine, probs) == {s for s in spoilt if s[0] in probs}, language
        assert len(mine) == sum(len(vector_case_ids(p)) for p in probs)


def test_missing_jdk_is_reported_not_skipped(monkeypatch, tmp_path):
    monkeypatch.setattr(lang_java.shutil, "which", lambda name: None)
    with pytest.raises(ToolchainMissing, match="javac"):
        lang_java.run(VECTORS_DIR, tmp_path)


def test_lucas_kanade_vector_agrees_with_first_order_flow():
    """The exact projection difference stays close to J(X) v dt (independent formula) on these points."""
    from flowtrack.camera import optical_flow_from_scene_flow, project
    from flowtrack.synth import make_scene
    from flowtrack_course.polyglot.problems.camera import LK_WINDOW, select_lk_features

    scene = make_scene(n_objects=3, n_frames=2, image_size=(240, 320), dt=0.1, noise=0.0, seed=0)
    f0, f1 = scene.frames
    gray = np.rint(f0.rgb.astype(float) @ [0.299, 0.587, 0.114]).astype(np.uint8)
    pix = f0.pixels
    X, v = f0.gt_points, f0.gt_flow
    exact = project(X + v * scene.dt, scene.camera) - np.stack([pix[:, 1], pix[:, 0]], 1)
    first = optical_flow_from_scene_flow(X, v, scene.dt, scene.camera)
    img = np.zeros((240, 320, 2))
    img[pix[:, 0], pix[:, 1]] = exact
    feats = select_lk_features(gray, f0.label_image, f1.label_image, img, LK_WINDOW // 2)
    assert len(feats) >= 10
    idx = np.full((240, 320), -1)
    idx[pix[:, 0], pix[:, 1]] = np.arange(len(pix))
    k = idx[feats[:, 0], feats[:, 1]]
    assert (f0.labels[k] > 0).all()  # every feature is on a moving object
    assert np.abs(exact[k]).max() > 1.0  # and moves by more than a pixel
    np.testing.assert_allclose(exact[k], first[k], atol=0.1)  # second-order terms are small
