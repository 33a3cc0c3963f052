"""The ports' shared test vectors: reproducible, well-formed, and right by independent oracles.

Oracles: filterpy's KalmanFilter and Q_discrete_white_noise, central differences, explicit inverses
with scipy's linear_sum_assignment, dense Kronecker solves with hand-built Laplacians, the true rigid
motion. Also the ``flowtrack ports`` runner's failure reporting (no compiler needed).
"""

from __future__ import annotations

import copy
import json
import math
import sys
import types

import numpy as np
import pytest
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import KalmanFilter as FilterpyKF
from scipy.optimize import linear_sum_assignment

from flowtrack_course.cli import main
from flowtrack_course.polyglot.base import ToolchainMissing
from flowtrack_course.polyglot.vectors import CaseResult
from flowtrack_course.ports import runner
from flowtrack_course.ports.vectors import (
    REGENERATION_RTOL,
    VECTORS_DIR,
    dumps,
    problem_names,
    vector_differences,
    write_vectors,
)
from oracles import central_difference_jacobian
from ports_helpers import perturbed_vectors

REQUIRED = {
    "kalman_cv2d",
    "white_noise_q",
    "projection_jacobian",
    "mahalanobis_assignment",
    "graph_scene_flow",
    "variational_scene_flow",
    "rigid_icp",
    "lucas_kanade",
    "steady_state_scalar",
}


def _load(problem: str) -> dict:
    return json.loads((VECTORS_DIR / f"{problem}.json").read_text())


def _cases(problem: str):
    return [pytest.param(c, id=c["id"]) for c in _load(problem)["cases"]]


def _close(got, expected, case) -> None:
    np.testing.assert_allclose(got, np.asarray(expected, float), rtol=case["rtol"], atol=case["atol"])


# ----------------------------------------------------------------------------------------------------
# reproducibility and schema
# ----------------------------------------------------------------------------------------------------
def test_regenerating_reproduces_the_committed_vectors_within_tolerance(tmp_path):
    """Numbers, not bytes: BLAS, CHOLMOD, open3d and OpenCV builds differ in the last bits."""
    written = write_vectors(tmp_path)
    assert {p.name for p in written} == {p.name for p in VECTORS_DIR.glob("*.json")}
    assert set(REGENERATION_RTOL) == set(problem_names())
    for p in written:
        problem = p.stem
        diffs = vector_differences(_load(problem), json.loads(p.read_text()), REGENERATION_RTOL[problem])
        assert not diffs, f"{p.name} changed on regeneration:\n" + "\n".join(diffs[:10])


def _largest_float(doc: dict) -> tuple[list, int | str]:
    """(container, key) of the largest-magnitude float in the first case's expected values."""
    best, where = -1.0, None

    def walk(holder, key):
        nonlocal best, where
        v = holder[key]
        if isinstance(v, float) and abs(v) > best:
            best, where = abs(v), (holder, key)
        elif isinstance(v, list):
            for i in range(len(v)):
                walk(v, i)
        elif isinstance(v, dict):
            for k in v:
                walk(v, k)

    walk(doc["cases"][0], "expected")
    assert where is not None and best > 0
    return where


@pytest.mark.parametrize("problem", sorted(REGENERATION_RTOL))
def test_the_regeneration_check_passes_ulps_and_fails_a_1e5_relative_change(problem):
    """On in-memory copies of the committed file: 4 ulps of one value pass, 1e-5 relative fails."""
    committed = _load(problem)
    rtol = REGENERATION_RTOL[problem]
    assert vector_differences(committed, copy.deepcopy(committed), rtol) == []
    ulps = copy.deepcopy(committed)
    holder, key = _largest_float(ulps)
    for _ in range(4):
        holder[key] = float(np.nextafter(holder[key], np.inf))
    assert holder[key] != _largest_float(committed)[0][key]
    assert vector_differences(committed, ulps, rtol) == []
    spoilt = copy.deepcopy(committed)
    holder, key = _largest_float(spoilt)
    holder[key] *= 1 + 1e-5
    diffs = vector_differences(committed, spoilt, rtol)
    assert len(diffs) == 1 and diffs[0].startswith(f"case {committed['cases'][0]['id']}: expected/"), diffs
    # a changed integer (e.g. a match index, a grey level) or a lost row is never within tolerance
    lost = copy.deepcopy(committed)
    first = lost["cases"][0]["expected"][sorted(lost["cases"][0]["expected"])[0]]
    if isinstance(first, list):
        first.pop()
        assert vector_differences(committed, lost, rtol)


def test_regeneration_tolerances_are_far_below_the_port_tolerances():
    """At each expected entry's largest value the regeneration bound is < 1/100 of the port's."""
    for problem, rtol in REGENERATION_RTOL.items():
        for case in _load(problem)["cases"]:
            for key, value in case["expected"].items():
                m = max((abs(v) for v in _numbers(value)), default=0.0)
                assert 2 * rtol * m <= (case["atol"] + case["rtol"] * m) / 100, (problem, case["id"], key)


def test_integer_values_must_match_exactly():
    doc = _load("mahalanobis_assignment")
    changed = copy.deepcopy(doc)
    changed["cases"][0]["expected"]["matches"][0][1] += 1
    assert any("integers differ" in d for d in vector_differences(doc, changed, 1.0))


def test_every_required_problem_is_registered_and_files_are_small():
    assert REQUIRED <= set(problem_names())
    assert sum(p.stat().st_size for p in VECTORS_DIR.glob("*.json")) < 2_000_000


def _numbers(value):
    if isinstance(value, dict):
        for v in value.values():
            yield from _numbers(v)
    elif isinstance(value, list):
        for v in value:
            yield from _numbers(v)
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        yield value


@pytest.mark.parametrize("path", sorted(VECTORS_DIR.glob("*.json")), ids=lambda p: p.stem)
def test_schema(path):
    text = path.read_text()
    doc = json.loads(text)
    assert dumps(doc) == text  # canonical form: sorted keys, repr floats
    assert doc["problem"] == path.stem
    ids = [c["id"] for c in doc["cases"]]
    assert ids and len(set(ids)) == len(ids)
    for c in doc["cases"]:
        assert set(c) == {"id", "input", "expected", "rtol", "atol"}
        assert isinstance(c["id"], str) and " " not in c["id"]
        assert c["rtol"] >= 0 and c["atol"] >= 0 and c["rtol"] + c["atol"] > 0
        assert c["input"] and c["expected"]
        assert all(math.isfinite(x) for x in _numbers(c))


# ----------------------------------------------------------------------------------------------------
# oracles
# ----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("case", _cases("kalman_cv2d"))
def test_kalman_cv2d_against_filterpy(case):
    inp = case["input"]
    dt, q, r = inp["dt"], inp["process_var"], inp["meas_var"]
    kf = FilterpyKF(dim_x=4, dim_z=2)
    kf.F = np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1]], float)
    kf.H = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0]])
    kf.Q = Q_discrete_white_noise(dim=2, dt=dt, var=q, block_size=2, order_by_dim=False)
    kf.R = r * np.eye(2)
    kf.x = np.array(inp["x0"], float).reshape(4, 1)
    kf.P = np.array(inp["P0"], float)
    positions = []
    for z in inp["measurements"]:
        kf.predict()
        kf.update(np.array(z, float).reshape(2, 1))
        positions.append(kf.x[:2, 0].copy())
    _close(np.array(positions), case["expected"]["positions"], case)
    _close(kf.P, case["expected"]["P_final"], case)


def test_kalman_syllabus_case_is_the_syllabus_run():
    case = next(c for c in _load("kalman_cv2d")["cases"] if c["id"] == "syllabus")
    inp = case["input"]
    assert inp["measurements"] == [[0.0, 0.0], [0.9, 0.1], [2.1, 0.2], [3.0, 0.1]]
    assert (inp["dt"], inp["process_var"], inp["meas_var"]) == (0.1, 1.0, 4.0)
    assert inp["x0"] == [0.0] * 4 and np.array_equal(inp["P0"], 1e3 * np.eye(4))
    assert max(len(c["input"]["measurements"]) for c in _load("kalman_cv2d")["cases"]) >= 1000


@pytest.mark.parametrize("case", _cases("white_noise_q"))
def test_white_noise_q_against_filterpy(case):
    inp = case["input"]
    Q = Q_discrete_white_noise(dim=2, dt=inp["dt"], var=inp["q"], block_size=inp["dim"], order_by_dim=False)
    _close(np.asarray(case["expected"]["Q"]), Q, case)


def test_white_noise_q_covers_dims_1_2_3():
    assert {c["input"]["dim"] for c in _load("white_noise_q")["cases"]} == {1, 2, 3}


@pytest.mark.parametrize("case", _cases("projection_jacobian"))
def test_projection_jacobian_against_central_differences(case):
    inp = case["input"]
    fx, fy, cx, cy = inp["fx"], inp["fy"], inp["cx"], inp["cy"]

    def project(X):  # (N, 3) -> (N, 2)
        return np.stack([fx * X[:, 0] / X[:, 2] + cx, fy * X[:, 1] / X[:, 2] + cy], axis=1)

    J = central_difference_jacobian(project, np.array([inp["X"]], float))[0]
    np.testing.assert_allclose(case["expected"]["J"], J, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("case", _cases("mahalanobis_assignment"))
def test_mahalanobis_assignment_against_inverse_and_scipy(case):
    inp = case["input"]
    zp, S, Z, gate = (np.array(inp[k], float) for k in ("z_pred", "S", "detections", "gate"))
    cost = np.array([[(z - zp[i]) @ np.linalg.inv(S[i]) @ (z - zp[i]) for z in Z] for i in range(len(zp))])
    _close(np.asarray(case["expected"]["cost"]), cost, case)
    # gated pairs get a cost larger than any sum of admissible ones, then are dropped
    r, c = linear_sum_assignment(np.where(cost <= gate, cost, 1e6))
    matches = sorted([int(i), int(j)] for i, j in zip(r, c) if cost[i, j] <= gate)
    assert case["expected"]["matches"] == matches


def test_assignment_gate_trap_is_present():
    case = next(c for c in _load("mahalanobis_assignment")["cases"] if c["id"] == "gate_trap")
    np.testing.assert_allclose(case["expected"]["cost"], [[0, 6], [6, 11]], atol=1e-12)
    assert case["expected"]["matches"] == [[0, 1], [1, 0]]


def _dense_knn_affinity(X, k, sigma):
    D = np.sqrt(((X[:, None, :] - X[None, :, :]) ** 2).sum(-1))
    W = np.zeros_like(D)
    for i in range(len(X)):
        order = [j for j in np.argsort(D[i], kind="stable") if j != i][:k]
        W[i, order] = np.exp(-((D[i, order] / sigma) ** 2))
    return np.maximum(W, W.T)


@pytest.mark.parametrize("case", _cases("graph_scene_flow"))
def test_graph_scene_flow_against_dense_kron_solve(case):
    inp = case["input"]
    X, Y = np.array(inp["points"]), np.array(inp["targets"])
    n = len(X)
    if "edges" in inp:
        W = np.zeros((n, n))
        for i, j, w in inp["edges"]:
            assert i < j
            W[int(i), int(j)] = W[int(j), int(i)] = w
    else:
        W = _dense_knn_affinity(X, inp["k"], inp["sigma"])
    L = np.diag(W.sum(1)) - W
    dt, lam = inp["dt"], inp["lam"]
    A = np.kron(dt**2 * np.eye(n) + lam * L, np.eye(3))  # row-major vec of the (N, 3) flow
    v = np.linalg.solve(A, dt * (Y - X).ravel())
    _close(np.asarray(case["expected"]["flow"]), v.reshape(n, 3), case)


def _grid_laplacian(H, W):
    L = np.zeros((H * W, H * W))
    for r in range(H):
        for c in range(W):
            for dr, dc in ((0, 1), (1, 0)):
                if r + dr < H and c + dc < W:
                    p, q = r * W + c, (r + dr) * W + c + dc
                    L[p, p] += 1
                    L[q, q] += 1
                    L[p, q] -= 1
                    L[q, p] -= 1
    return L


@pytest.mark.parametrize("case", _cases("variational_scene_flow"))
def test_variational_scene_flow_against_dense_solve(case):
    inp = case["input"]
    a, b = np.array(inp["a"]), np.array(inp["b"])
    C, H, W = a.shape
    A = inp["dt"] ** 2 * np.eye(H * W) + inp["lam"] * _grid_laplacian(H, W)
    v = np.stack([np.linalg.solve(A, inp["dt"] * (b[c] - a[c]).ravel()).reshape(H, W) for c in range(C)])
    _close(np.asarray(case["expected"]["v"]), v, case)
    assert C in (1, 3)


def test_variational_has_one_and_three_component_cases():
    assert {len(c["input"]["a"]) for c in _load("variational_scene_flow")["cases"]} == {1, 3}


@pytest.mark.parametrize("case", _cases("rigid_icp"))
def test_rigid_icp_transform_is_rigid_and_near_the_true_motion(case):
    T = np.array(case["expected"]["T"])
    T_true = np.array(case["expected"]["T_true"])
    R = T[:3, :3]
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-9)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-9)
    np.testing.assert_array_equal(T[3], [0, 0, 0, 1])
    # 1 mm noise on a 12 x 8 x 5 cm box: the estimate is within a few mm / mrad of the truth ...
    assert np.abs(T - T_true).max() < 5e-3
    # ... and the motion is much larger than that, so the comparison means something
    assert np.abs(T_true - np.eye(4)).max() > 0.02
    src, dst = np.array(case["input"]["source"]), np.array(case["input"]["target"])
    rms = np.sqrt((((src @ R.T + T[:3, 3]) - dst) ** 2).sum(1).mean())
    assert rms < 0.0025  # noise is 1 mm per axis: sqrt(3) mm expected


def test_perturbed_vectors_spoil_one_case_per_problem_beyond_tolerance(tmp_path):
    problems = ["white_noise_q", "mahalanobis_assignment", "rigid_icp"]
    folder, spoilt = perturbed_vectors(tmp_path, problems)
    assert {p for p, _ in spoilt} == set(problems) and len(spoilt) == 3
    for problem in problems:
        old, new = _load(problem), json.loads((folder / f"{problem}.json").read_text())
        for c_old, c_new in zip(old["cases"], new["cases"]):
            a, b = np.array(list(_numbers(c_old["expected"]))), np.array(list(_numbers(c_new["expected"])))
            changed = np.flatnonzero(a != b)
            if (problem, c_old["id"]) in spoilt:
                assert changed.size == 1
                i = changed[0]
                assert abs(b[i] - a[i]) > 2 * (c_old["atol"] + c_old["rtol"] * abs(a[i]))
            else:
                assert changed.size == 0
    untouched = folder / "kalman_cv2d.json"
    assert untouched.read_bytes() == (VECTORS_DIR / "kalman_cv2d.json").read_bytes()


# ----------------------------------------------------------------------------------------------------
# the runner reports every kind of failure (fake language modules, no compiler needed)
# ----------------------------------------------------------------------------------------------------
def _fake_module(monkeypatch, name, run):
    mod = types.ModuleType(name)
    mod.PORTS = ("fake-a", "fake-b")
    mod.run = run
    monkeypatch.setitem(sys.modules, name, mod)
    monkeypatch.setitem(runner.LANG_MODULES, "cpp", name)


def test_runner_reports_missing_toolchain_and_exits_nonzero(monkeypatch, capsys):
    def run(vectors_dir, build_dir):
        raise ToolchainMissing("no compiler")

    _fake_module(monkeypatch, "fake_lang_missing", run)
    results = runner.run_ports(["cpp"])
    assert [(r.language, r.problem, r.passed) for r in results] == [
        ("fake-a", "toolchain", False),
        ("fake-b", "toolchain", False),
    ]
    assert main(["ports", "--lang", "cpp", "--no-progress"]) == 1
    assert "no compiler" in capsys.readouterr().out


def test_runner_fails_a_port_without_cases_and_passes_a_clean_run(monkeypatch):
    def run(vectors_dir, build_dir):
        return [CaseResult("fake-a", "white_noise_q", "x", True, 0.0)]

    _fake_module(monkeypatch, "fake_lang_partial", run)
    results = runner.run_ports(["cpp"])
    assert [(r.language, r.problem, r.passed) for r in results] == [
        ("fake-a", "white_noise_q", True),
        ("fake-b", "no-cases", False),
    ]
    assert main(["ports", "--lang", "cpp", "--no-progress"]) == 1

    def run_ok(vectors_dir, build_dir):
        return [CaseResult(lang, "p", "x", True, 0.0) for lang in ("fake-a", "fake-b")]

    _fake_module(monkeypatch, "fake_lang_ok", run_ok)
    assert main(["ports", "--lang", "cpp", "--no-progress"]) == 0


def test_runner_rejects_unknown_language_and_missing_vectors(tmp_path):
    with pytest.raises(ValueError, match="langs"):
        runner.run_ports(["fortran"])
    with pytest.raises(FileNotFoundError, match="vectors_dir"):
        runner.run_ports(["cpp"], vectors_dir=tmp_path)
