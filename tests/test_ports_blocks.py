"""The filter as a bdsim block diagram on the ``kalman_cv2d`` vectors."""

from __future__ import annotations

import numpy as np
import pytest

from flowtrack_course.polyglot import blocks as lang_blocks
from flowtrack_course.ports.vectors import VECTORS_DIR
from ports_helpers import BUILD_DIR, assert_every_case_passes, failing_cases, perturbed_vectors, run_port

pytestmark = pytest.mark.xdist_group("ports-blocks")


@pytest.fixture(scope="module")
def blocks_results():
    return run_port(lang_blocks.run, VECTORS_DIR, BUILD_DIR)


def test_port_passes_every_vector_case(blocks_results):
    assert_every_case_passes(blocks_results, "kalman_cv2d")
    assert (BUILD_DIR / "blocks" / "kalman_cv2d.dot").stat().st_size > 0


def test_harness_reports_exactly_the_perturbed_cases(blocks_results, tmp_path):
    folder, spoilt = perturbed_vectors(tmp_path, ["kalman_cv2d"])
    results = lang_blocks.run(folder, tmp_path)
    assert failing_cases(results, ["kalman_cv2d"]) == spoilt


def test_diagram_matches_filterpy_with_the_syllabus_q_difference():
    """Against filterpy (independent), and the syllabus' blkdiag Q gives a visibly different answer."""
    from filterpy.kalman import KalmanFilter

    dt, q, r = 0.1, 2.0, 0.5
    rng = np.random.default_rng(3)
    Z = np.cumsum(rng.normal(size=(30, 2)), axis=0)
    pos, P = lang_blocks.simulate(dt, q, r, np.zeros(4), 10 * np.eye(4), Z)
    Q1d = q * np.array([[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]])
    out = {}
    for name, Q in (("kron", np.kron(Q1d, np.eye(2))), ("blkdiag", np.kron(np.eye(2), Q1d))):
        kf = KalmanFilter(dim_x=4, dim_z=2)
        kf.F = np.eye(4) + dt * np.eye(4, k=2)
        kf.H = np.eye(2, 4)
        kf.Q, kf.R, kf.P = Q, r * np.eye(2), 10 * np.eye(4)
        track = []
        for z in Z:
            kf.predict()
            kf.update(z)
            track.append(kf.x[:2].ravel().copy())
        out[name] = (np.array(track), kf.P.copy())
    np.testing.assert_allclose(pos, out["kron"][0], rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(P, out["kron"][1], rtol=1e-10, atol=1e-12)
    assert np.abs(P - out["blkdiag"][1]).max() > 1e-3


def test_bad_input_is_rejected():
    with pytest.raises(ValueError, match="measurements"):
        lang_blocks.simulate(0.1, 1.0, 1.0, np.zeros(4), np.eye(4), [[1.0, 2.0, 3.0]])
    with pytest.raises(ValueError, match="dt"):
        lang_blocks.simulate(-0.1, 1.0, 1.0, np.zeros(4), np.eye(4), [[1.0, 2.0]])


def test_simulation_leaves_sys_argv_alone(monkeypatch, tmp_path):
    """bdsim parses sys.argv by default (it took pytest's ``-p x`` for ``--pickle x``)."""
    import sys

    argv = ["prog", "-p", str(tmp_path / "pickled"), "-n", "2"]
    monkeypatch.setattr(sys, "argv", list(argv))
    lang_blocks.simulate(0.1, 1.0, 1.0, np.zeros(4), np.eye(4), [[1.0, 2.0]])
    assert sys.argv == argv
    assert not (tmp_path / "pickled").exists()
