r"""The constant-velocity Kalman filter as a Simulink-style block diagram, simulated with bdsim.

The diagram (described with a picture in ``cpp_java_matlab_ports/blocks/README.md``) is discrete
time: one clock of period :math:`\Delta t` drives two unit delays (``ZOH`` blocks) that hold the
filter state :math:`\hat x_{k-1}` (4) and the covariance :math:`P_{k-1}` (16, row-major). Per tick

.. math::

    \hat x_k^- &= F \hat x_{k-1}                      &&\text{(GAIN F)}\\
    P_k^-, K_k &= \text{cov}(P_{k-1})                 &&\text{(FUNCTION covariance)}\\
    \nu_k &= z_k - H \hat x_k^-                       &&\text{(GAIN H, SUM +-)}\\
    \hat x_k &= \hat x_k^- + K_k \nu_k                &&\text{(FUNCTION K·ν, SUM ++)}

with ``cov``: :math:`P^- = F P F^\top + Q`, :math:`S = H P^- H^\top + R`,
:math:`K = P^- H^\top S^{-1}`, :math:`P = (I - K H) P^-`, and ``Q = Q1d ⊗ I2`` (the syllabus'
``blkdiag(Q1d, Q1d)`` is wrong for the state order ``[px, py, vx, vy]``). The measurement source is
``TIME`` followed by a ``FUNCTION`` that looks up :math:`z_k` (bdsim's first clock tick is at
:math:`t = \Delta t`, so tick :math:`k` reads measurement :math:`k-1`). The clock records the delay
states after every tick: row :math:`k` of ``out.clk.X`` is :math:`(\hat x_k, \mathrm{vec}\,P_k)`.
"""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

from .base import Toolchain, python_module
from .vectors import CaseResult, compare_outputs, failure

__all__ = ["PORTS", "TOOLCHAIN", "run", "build_diagram", "simulate"]

#: The ports this module runs (the names in ``flowtrack ports``' table).
PORTS: tuple[str, ...] = ("blocks",)
PROBLEMS: tuple[str, ...] = ("kalman_cv2d",)
#: A port only: students do not answer in block diagrams (no ``extension``).
TOOLCHAIN = Toolchain(
    "blocks",
    "Simulink-style block diagram (bdsim)",
    port_requirements=(python_module("bdsim", package='-e ".[ports]" (PyPI bdsim)'),),
)


def _model(dt: float, q: float, r: float):
    import numpy as np  # numpy and bdsim load when a diagram is built: ``flowtrack --help`` lists this port

    F = np.eye(4)
    F[0, 2] = F[1, 3] = dt
    H = np.eye(2, 4)
    Q1d = q * np.array([[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]])
    return F, H, np.kron(Q1d, np.eye(2)), r * np.eye(2)


def build_diagram(dt: float, process_var: float, meas_var: float, x0, P0, measurements):
    """Build (not run) the filter's block diagram.

    Parameters
    ----------
    dt : float, > 0
    process_var, meas_var : float
        ``q`` (>= 0) and the measurement variance ``r`` (> 0).
    x0 : array_like, shape (4,)
    P0 : array_like, shape (4, 4)
    measurements : array_like, shape (K, 2)

    Returns
    -------
    (bdsim.BDSim, BlockDiagram)
        The simulator and the compiled diagram.
    """
    import bdsim
    import numpy as np

    if not (isinstance(dt, (int, float)) and dt > 0):
        raise ValueError(f"dt: expected a number > 0, got {dt!r}")
    if not meas_var > 0 or not process_var >= 0:
        raise ValueError("process_var, meas_var: expected process_var >= 0 and meas_var > 0")
    x0 = np.asarray(x0, dtype=float)
    P0 = np.asarray(P0, dtype=float)
    Z = np.asarray(measurements, dtype=float)
    if x0.shape != (4,) or P0.shape != (4, 4):
        raise ValueError(f"x0, P0: expected shapes (4,) and (4, 4), got {x0.shape} and {P0.shape}")
    if Z.ndim != 2 or Z.shape[1] != 2 or len(Z) == 0:
        raise ValueError(f"measurements: expected shape (K, 2) with K >= 1, got {Z.shape}")
    F, H, Q, R = _model(float(dt), float(process_var), float(meas_var))
    I4 = np.eye(4)

    def covariance(p):
        P = np.asarray(p).reshape(4, 4)
        Pp = F @ P @ F.T + Q
        S = H @ Pp @ H.T + R
        K = Pp @ H.T @ np.linalg.inv(S)
        return [K, ((I4 - K @ H) @ Pp).ravel()]

    def measurement(t):
        k = min(max(int(np.rint(t / dt)) - 1, 0), len(Z) - 1)
        return Z[k]

    # sysargs=False: bdsim would otherwise parse (and rewrite!) sys.argv, e.g. take pytest's -p as its
    # --pickle option; stdout is silenced because bdsim reports optional toolboxes it cannot find
    with contextlib.redirect_stdout(io.StringIO()):
        sim = bdsim.BDSim(sysargs=False, animation=False, graphics=False, progress=False, verbose=False)
    bd = sim.blockdiagram(name="kalman_cv2d")
    clk = bd.clock(dt, offset=0.0, name="clk")
    x_delay = bd.ZOH(clk, x0=x0, name="x_delay")
    P_delay = bd.ZOH(clk, x0=P0.ravel(), name="P_delay")
    time = bd.TIME(name="t")
    z = bd.FUNCTION(measurement, nin=1, name="measurement")
    gain_F = bd.GAIN(F, premul=True, name="F")
    gain_H = bd.GAIN(H, premul=True, name="H")
    cov = bd.FUNCTION(covariance, nin=1, nout=2, name="covariance")
    innovation = bd.SUM("+-", name="innovation")
    correction = bd.FUNCTION(lambda K, nu: K @ nu, nin=2, name="K_nu")
    update = bd.SUM("++", name="x_update")

    bd.connect(time, z)
    bd.connect(x_delay, gain_F)
    bd.connect(gain_F, gain_H, update[0])
    bd.connect(z, innovation[0])
    bd.connect(gain_H, innovation[1])
    bd.connect(P_delay, cov)
    bd.connect(cov[0], correction[0])
    bd.connect(innovation, correction[1])
    bd.connect(correction, update[1])
    bd.connect(update, x_delay)
    bd.connect(cov[1], P_delay)
    with contextlib.redirect_stdout(io.StringIO()):
        bd.compile()
    return sim, bd


def simulate(dt, process_var, meas_var, x0, P0, measurements, dotfile: Path | None = None):
    """Simulate the diagram over all measurements.

    Returns
    -------
    positions : ndarray, shape (K, 2)
        Filtered position after each update.
    P : ndarray, shape (4, 4)
        Covariance after the last update.
    """
    import numpy as np

    sim, bd = build_diagram(dt, process_var, meas_var, x0, P0, measurements)
    if dotfile is not None:
        bd.dotfile(str(dotfile))
    K = len(measurements)
    with contextlib.redirect_stdout(io.StringIO()):
        out = sim.run(bd, T=(K + 0.5) * dt)
    X = np.asarray(out.clk.X)
    if X.shape[0] != K:
        raise RuntimeError(f"bdsim recorded {X.shape[0]} clock ticks, expected {K}")
    return X[:, :2].copy(), X[-1, 4:].reshape(4, 4).copy()


def _export_picture(build: Path) -> None:
    """Write the diagram as Graphviz ``.dot`` (and ``.png`` when ``dot`` is installed) to ``build``."""
    import shutil
    import subprocess

    import numpy as np

    dot = build / "kalman_cv2d.dot"
    simulate(0.1, 1.0, 4.0, np.zeros(4), 1e3 * np.eye(4), [[0.0, 0.0]], dotfile=dot)
    exe = shutil.which("dot")
    if exe is not None:
        subprocess.run([exe, "-Tpng", "-o", str(build / "kalman_cv2d.png"), str(dot)], check=False)


def run(vectors_dir: Path, build_dir: Path) -> list[CaseResult]:
    """Simulate the diagram on every ``kalman_cv2d`` case and compare with the case's tolerance.

    Parameters
    ----------
    vectors_dir : Path
    build_dir : Path
        The ports' build root; the diagram picture goes to ``build_dir/blocks/``.

    Returns
    -------
    list of CaseResult

    Raises
    ------
    flowtrack_course.polyglot.base.ToolchainMissing
        bdsim is not installed (``pip install -e ".[ports]"``).
    """
    import numpy as np

    TOOLCHAIN.check(ports=True)
    build = Path(build_dir) / "blocks"
    build.mkdir(parents=True, exist_ok=True)
    _export_picture(build)
    results = []
    for problem in PROBLEMS:
        path = Path(vectors_dir) / f"{problem}.json"
        if not path.exists():
            results.append(failure("blocks", problem, f"vector file {path.name} missing"))
            continue
        for case in json.loads(path.read_text())["cases"]:
            inp = case["input"]
            try:
                pos, P = simulate(
                    inp["dt"],
                    inp["process_var"],
                    inp["meas_var"],
                    inp.get("x0", np.zeros(4)),
                    inp.get("P0", 1e3 * np.eye(4)),
                    inp["measurements"],
                )
            except Exception as exc:  # any simulation failure fails this case
                results.append(failure("blocks", problem, f"{type(exc).__name__}: {exc}", case["id"]))
                continue
            ok, worst, msg = compare_outputs(
                {"positions": pos, "P_final": P}, case["expected"], float(case["rtol"]), float(case["atol"])
            )
            results.append(CaseResult("blocks", problem, case["id"], ok, worst, msg))
    return results
