r"""What the synthetic scenes contain: options, workspace, random placement and the scripted scenarios.

A scenario is data: :func:`scenario_script` returns, without randomness, the shapes and straight
paths of the scripted objects and the static occluder; :data:`SCENARIO_MIN_OBJECTS` says how many
moving objects each needs. Random objects get non-colliding paths inside the workspace
(:data:`X_RANGE` × :data:`Y_RANGE` on the table) from :func:`random_trajectories`.
:func:`flowtrack.synth.make_scene` puts it together. Part of :mod:`flowtrack.synth`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._validation import as_array, nonnegative
from ..camera import PinholeCamera
from .raycast import look_at
from .shapes import ArcTrajectory, Body, Box, Cylinder, PlanarTrajectory

__all__ = [
    "LIGHT_W",
    "OPTIONS",
    "PALETTE",
    "SCENARIOS",
    "SCENARIO_MIN_OBJECTS",
    "TURNING_ARC",
    "TURNING_SHAPE",
    "X_RANGE",
    "Y_RANGE",
    "default_camera",
    "parse_options",
    "random_shape",
    "random_trajectories",
    "scenario_script",
    "static_occluder",
    "straight_trajectory",
    "turning_script",
]

#: The scenarios :func:`flowtrack.synth.make_scene` knows (``scenario=`` option).
SCENARIOS = ("default", "crossing", "occlusion", "mixed", "turning")

#: Base colours of the moving objects (RGB in [0, 255]), drawn in a seeded random order.
PALETTE = np.array(
    [
        [220, 50, 40],  # red
        [40, 170, 70],  # green
        [40, 90, 220],  # blue
        [235, 190, 30],  # yellow
        [190, 60, 200],  # magenta
        [30, 190, 200],  # cyan
        [240, 130, 30],  # orange
        [120, 80, 40],  # brown
    ],
    dtype=np.float64,
)
#: Unit vector towards the light, world frame.
LIGHT_W = np.array([0.3, -0.5, 1.0]) / np.linalg.norm([0.3, -0.5, 1.0])


# ----------------------------------------------------------------------------------------------
# scene generation
# ----------------------------------------------------------------------------------------------
#: The ``**options`` of :func:`flowtrack.synth.make_scene` and their defaults.
OPTIONS = {
    "scenario": "default",
    "shapes": None,
    "speed": (0.06, 0.15),
    "max_angular_speed": 0.8,
    "bend": 0.08,
    "wall": True,
    "texture": True,
}

# workspace on the table (world x-y, metres) that the default camera sees with margin
X_RANGE = (-0.32, 0.32)
Y_RANGE = (-0.05, 0.45)


def default_camera(image_size) -> tuple[PinholeCamera, np.ndarray]:
    """The scenes' camera for ``image_size = (H, W)``: intrinsics (f = 0.9 W) and pose :math:`T_{wc}`."""
    H, W = image_size
    f = 0.9 * W
    cam = PinholeCamera(f, f, (W - 1) / 2.0, (H - 1) / 2.0, width=W, height=H)
    T_wc = look_at([0.0, -0.6, 0.65], [0.0, 0.2, 0.0])
    return cam, T_wc


def random_shape(rng: np.random.Generator, kind: str):
    """A random ``kind`` of shape: a box (half extents 3.5–6 cm, half height 3.5–7 cm) or a cylinder
    (radius 3.5–5.5 cm, half height 4–8 cm)."""
    if kind == "box":
        return Box((rng.uniform(0.035, 0.06), rng.uniform(0.035, 0.06), rng.uniform(0.035, 0.07)))
    return Cylinder(rng.uniform(0.035, 0.055), rng.uniform(0.04, 0.08))


def _collides(tr: PlanarTrajectory, r: float, others, times) -> bool:
    P = tr.position(times)[:, :2]
    for tr2, r2 in others:
        Q = tr2.position(times)[:, :2]
        if (np.linalg.norm(P - Q, axis=1) < r + r2 + 0.02).any():
            return True
    return False


def _in_workspace(tr: PlanarTrajectory, r: float, times) -> bool:
    P = tr.position(times)[:, :2]
    return bool(
        (P[:, 0] - r >= X_RANGE[0]).all()
        and (P[:, 0] + r <= X_RANGE[1]).all()
        and (P[:, 1] - r >= Y_RANGE[0]).all()
        and (P[:, 1] + r <= Y_RANGE[1]).all()
    )


# Random objects are placed one after the other; when one finds no free path (crowded scenes), all of
# them are placed again, up to this many times, continuing the same random stream (deterministic by
# seed; a scene placed at the first try is exactly what it always was).
_PLACEMENT_ROUNDS = 100


def random_trajectories(rng, objects, scripted, duration, opts, placed, times, static_discs):
    """Random non-colliding paths for the objects not in ``scripted`` (dict id -> trajectory)."""
    for round_ in range(_PLACEMENT_ROUNDS):
        taken, chosen = list(placed), {}
        try:
            for k in objects:
                if k in scripted:
                    continue
                chosen[k] = _random_trajectory(rng, objects[k], duration, opts, taken, times, static_discs)
                taken.append((chosen[k], objects[k].radius))
            return chosen
        except RuntimeError:
            if round_ == _PLACEMENT_ROUNDS - 1:
                raise
    raise AssertionError("unreachable")  # pragma: no cover


def _random_trajectory(rng, shape, duration, opts, others, times, static_discs) -> PlanarTrajectory:
    r = shape.radius
    lo_s, hi_s = opts["speed"]
    for _ in range(500):
        p0 = np.array([rng.uniform(*X_RANGE), rng.uniform(*Y_RANGE)])
        ang = rng.uniform(0, 2 * np.pi)
        speed = rng.uniform(lo_s, hi_s)
        p1 = p0 + speed * duration * np.array([np.cos(ang), np.sin(ang)])
        tr = PlanarTrajectory(
            tuple(p0),
            tuple(p1),
            duration=duration,
            z=shape.half_height,
            theta0=rng.uniform(-np.pi, np.pi),
            omega=rng.uniform(-1, 1) * opts["max_angular_speed"],
            bend=rng.uniform(-1, 1) * opts["bend"],
        )
        if _in_workspace(tr, r, times) and not _collides(tr, r, others + static_discs, times):
            return tr
    raise RuntimeError(
        f"could not place a non-colliding trajectory in the workspace ({_PLACEMENT_ROUNDS} rounds of 500 "
        "tries per object); use fewer objects (n_objects) or a lower speed"
    )


def straight_trajectory(rng, p0, p1, duration, shape, opts) -> PlanarTrajectory:
    """Straight path ``p0 -> p1`` resting on the table, random start angle and spin (scenarios)."""
    theta0 = rng.uniform(-np.pi, np.pi)
    omega = rng.uniform(-1, 1) * opts["max_angular_speed"]
    return PlanarTrajectory(p0, p1, duration, shape.half_height, theta0, omega, 0.0)


#: Fewest moving objects each scripted scenario needs (its scripted objects are ids 1..n).
SCENARIO_MIN_OBJECTS = {"crossing": 2, "occlusion": 1, "mixed": 3, "turning": 1}
_CROSSED_HALF_EXTENTS = (0.04, 0.04, 0.035)  # half extents of the low object that gets crossed
_HIDING_HALF_EXTENTS = (0.03, 0.03, 0.035)  # half extents of the small object that hides behind an occluder


def _upright(kind: str, half_extents: tuple) -> Box | Cylinder:
    """``Box(half_extents)``; for ``kind="cylinder"`` the cylinder of radius ``a``, half height ``c``."""
    a, b, c = half_extents
    return Box((a, b, c)) if kind == "box" else Cylinder(a, c)


def scenario_script(scenario: str, kinds: Sequence[str]) -> tuple[dict, tuple | None]:
    """What a scripted scenario places, as data: no randomness here.

    Returns
    -------
    paths : dict[int, (Box | Cylinder, (float, float), (float, float))]
        Object id -> (shape, start, end) of a straight path on the table (world x-y at t = 0 and at
        the end of the sequence); empty for ``"default"``.
    occluder : ((float, float, float), (float, float)) or None
        Half extents and world x-y of the static box standing on the table.
    """
    if scenario == "crossing":
        # a tall object 1 near the camera crosses in front of a low object 2 further away
        s1, s2 = _upright(kinds[0], (0.05, 0.045, 0.09)), _upright(kinds[1], _CROSSED_HALF_EXTENTS)
        y1, y2 = 0.02 + s1.radius, 0.40 - s2.radius
        x = X_RANGE[1] - max(s1.radius, s2.radius) - 0.01
        return {1: (s1, (-x, y1), (x, y1)), 2: (s2, (x, y2), (-x, y2))}, None
    if scenario == "occlusion":
        # object 1 (small, low) slides behind a static tall box standing between it and the camera
        s1 = _upright(kinds[0], _HIDING_HALF_EXTENTS)
        return {1: (s1, (-0.26, 0.36), (0.26, 0.36))}, ((0.075, 0.03, 0.13), (0.0, 0.10))
    if scenario == "mixed":
        # the crossing pair on shorter paths: 1 (taller, near) passes in front of 2 (low, middle of the
        # table) around the middle of the sequence; and 3 (small, far) slides behind a static box
        s1, s2 = _upright(kinds[0], (0.045, 0.04, 0.11)), _upright(kinds[1], _CROSSED_HALF_EXTENTS)
        s3 = _upright(kinds[2], _HIDING_HALF_EXTENTS)
        y1, y3 = 0.01 + s1.radius, 0.44 - s3.radius
        paths = {1: (s1, (-0.2, y1), (0.16, y1)), 2: (s2, (0.2, 0.22), (-0.2, 0.22)),
                 3: (s3, (-0.05, y3), (0.3, y3))}
        return paths, ((0.05, 0.02, 0.07), (0.15, 0.31))
    if scenario == "turning":
        return turning_script(), None
    return {}, None


#: the turning object: an upright cylinder (its visible-surface centroid turns with its centre)
TURNING_SHAPE = (0.045, 0.045, 0.05)
TURNING_ARC = {"center": (0.0, 0.2), "radius": 0.13, "omega": 1.0, "phase": -np.pi / 2}


def turning_script() -> dict:
    """Object 1 of the ``"turning"`` scenario: a cylinder going around an arc at 1 rad/s (0.13 m/s)."""
    shape = _upright("cylinder", TURNING_SHAPE)
    return {1: (shape, ArcTrajectory(**TURNING_ARC, z=shape.half_height))}


def static_occluder(half_extents: tuple, xy: tuple, T_cw: np.ndarray, duration: float, tex: float):
    """The grey box standing on the table at world ``xy`` (a label-0 Body) and its footprint disc."""
    occ = Box(half_extents)
    T_wocc = np.eye(4)
    T_wocc[:3, 3] = [xy[0], xy[1], occ.half_extents[2]]
    body = Body(occ, T_cw @ T_wocc, 0, (110.0, 110.0, 110.0), 0.03 * tex)
    return body, (PlanarTrajectory(xy, xy, duration, 0.0), occ.radius)


def parse_options(options: dict) -> dict:
    """:data:`OPTIONS` updated by ``options``, validated (``TypeError`` for unknown names)."""
    unknown = set(options) - set(OPTIONS)
    if unknown:
        raise TypeError(f"make_scene got unknown option(s) {sorted(unknown)}; known: {sorted(OPTIONS)}")
    opts = {**OPTIONS, **options}
    if opts["scenario"] not in SCENARIOS:
        raise ValueError(f"scenario must be one of {SCENARIOS}, got {opts['scenario']!r}")
    sp = as_array(opts["speed"], "speed", (2,))
    if sp[0] <= 0 or sp[1] < sp[0]:
        raise ValueError(f"speed must be (low, high) with 0 < low <= high, got {sp.tolist()}")
    opts["speed"] = (float(sp[0]), float(sp[1]))
    opts["max_angular_speed"] = nonnegative(opts["max_angular_speed"], "max_angular_speed")
    opts["bend"] = nonnegative(opts["bend"], "bend")
    return opts
