r"""The synthetic RGB-D sequence: :class:`Frame`, :class:`Scene` and :func:`make_scene`.

Ground truth per frame :math:`t_i = i\,\Delta t`, for each valid pixel with noiseless surface point
:math:`X` owned by object :math:`k` with object-to-camera pose :math:`T_k(t)`:

.. math::  v(X) = \frac{T_k(t_{i+1})\,T_k(t_i)^{-1} X - X}{\Delta t}.

Part of :mod:`flowtrack.synth` (see there for the whole model).
"""

from __future__ import annotations

import numbers
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np

from .._graph import apply_transform
from .._validation import nonnegative, positive, positive_int
from ..camera import PinholeCamera, backproject, project
from .raycast import cast_into, copy_cast, empty_cast, ray_directions, shade
from .scenarios import (
    LIGHT_W,
    PALETTE,
    SCENARIO_MIN_OBJECTS,
    default_camera,
    parse_options,
    random_shape,
    random_trajectories,
    scenario_script,
    static_occluder,
    straight_trajectory,
)
from .shapes import Body, PlanarTrajectory, Plane

__all__ = ["Frame", "Scene", "make_scene"]


# ----------------------------------------------------------------------------------------------
# scene containers
# ----------------------------------------------------------------------------------------------
@dataclass
class Frame:
    """One RGB-D frame with exact ground truth.

    Attributes
    ----------
    index : int
        Frame number ``i``; its time is ``i * dt``.
    time : float
    depth : ndarray, shape (H, W)
        Metric depth Z with noise, 0 where no surface is hit (never, with the table and wall).
    depth_gt : ndarray, shape (H, W)
        Noiseless depth.
    rgb : ndarray, shape (H, W, 3) uint8
    label_image : ndarray, shape (H, W) int
        0 static, 1..K objects, -1 no surface.
    points : ndarray, shape (N, 3)
        Back-projection of ``depth`` at the valid pixels (row-major order), camera frame.
    labels : ndarray, shape (N,) int
        Label of each point (0 static, 1..K object id).
    gt_flow : ndarray, shape (N, 3)
        Exact velocity (m/s) of each point's *noiseless* surface point over ``[t, t + dt]``.
    gt_poses : dict[int, ndarray (4, 4)]
        Object-to-camera pose of each moving object at this frame.
    visible : dict[int, int]
        Number of pixels of each moving object in this frame (0 = fully occluded).
    """

    index: int
    time: float
    depth: np.ndarray
    depth_gt: np.ndarray
    rgb: np.ndarray
    label_image: np.ndarray
    points: np.ndarray
    labels: np.ndarray
    gt_flow: np.ndarray
    gt_poses: dict
    visible: dict
    _camera: PinholeCamera = field(repr=False, default=None)
    _gt_points: np.ndarray | None = field(repr=False, default=None)

    @property
    def valid(self) -> np.ndarray:
        """Boolean (H, W) mask of the pixels that have a point."""
        return self.depth_gt > 0

    @property
    def pixels(self) -> np.ndarray:
        """``(N, 2)`` int ``(row, col)`` of each point (same order as ``points``)."""
        return np.argwhere(self.valid)

    @property
    def gt_points(self) -> np.ndarray:
        """``(N, 3)`` noiseless surface points (back-projection of ``depth_gt``; a fresh array)."""
        if self._gt_points is not None:  # computed by make_scene
            return self._gt_points.copy()
        return backproject(self.depth_gt, self._camera)[self.valid]


@dataclass
class Scene:
    """A synthetic sequence; see :func:`make_scene`.

    Attributes
    ----------
    camera : PinholeCamera
        Intrinsics with ``width`` and ``height``.
    dt : float
        Time between frames (s).
    frames : list of Frame
    camera_pose : ndarray, shape (4, 4)
        Camera-to-world transform :math:`T_{wc}` (world: table plane z = 0, z up).
    objects : dict[int, Box | Cylinder]
        Shape of each moving object (id 1..K), in its own frame (origin = geometric centre).
    trajectories : dict[int, PlanarTrajectory]
        World motion of each moving object.
    static_bodies : list of Body
        Table, wall and static occluders (label 0), posed in the camera frame.
    colors : dict[int, ndarray (3,)]
        Base colour of each object.
    scenario : str
    """

    camera: PinholeCamera
    dt: float
    frames: list
    camera_pose: np.ndarray
    objects: dict
    trajectories: dict
    static_bodies: list
    colors: dict
    scenario: str = "default"

    def __len__(self) -> int:
        return len(self.frames)

    def __iter__(self) -> Iterator[Frame]:
        return iter(self.frames)

    @property
    def object_ids(self) -> list[int]:
        """Ids of the moving objects, ``[1, ..., K]``."""
        return sorted(self.objects)

    def pose(self, object_id: int, t: float) -> np.ndarray:
        """Object-to-camera pose :math:`T_{cw} T_{wo}(t)` at any time ``t`` (4, 4)."""
        if object_id not in self.trajectories:
            raise ValueError(f"object_id must be one of {self.object_ids}, got {object_id}")
        return np.linalg.inv(self.camera_pose) @ self.trajectories[object_id].pose(float(t))

    def _frame_index(self, frame_index) -> int:
        if isinstance(frame_index, bool) or not isinstance(frame_index, numbers.Integral):
            raise TypeError(f"frame_index must be an int, got {type(frame_index).__name__}")
        n = len(self.frames)
        if not -n <= frame_index < n:
            raise ValueError(f"frame_index must be in [-{n}, {n}), got {frame_index}")
        return int(frame_index) % n

    def object_centroids(self, frame_index: int) -> dict[int, np.ndarray]:
        """Centre (origin of the object frame) of every moving object in the camera frame.

        Returns
        -------
        dict[int, ndarray (3,)]
            All objects, visible or not (see ``frames[i].visible``).
        """
        i = self._frame_index(frame_index)
        return {k: T[:3, 3].copy() for k, T in self.frames[i].gt_poses.items()}

    def ground_truth_tracks(self, coords: str = "camera", min_visible: int = 1) -> list[dict]:
        """Per-frame ground-truth object positions for tracking metrics.

        Parameters
        ----------
        coords : {"camera", "world", "table", "image"}
            ``camera``: centre in the camera frame (3,); ``world``: in the world frame (3,);
            ``table``: world x-y on the table (2,); ``image``: projected centre in pixels (x, y).
        min_visible : int, >= 0
            Leave out objects with fewer visible pixels in that frame (0 keeps all), so that
            trackers are not charged for fully occluded objects.

        Returns
        -------
        list of dict[int, ndarray]
            One ``{object_id: position}`` per frame, the format of :func:`flowtrack.metrics.clear_mot`.
        """
        if coords not in ("camera", "world", "table", "image"):
            raise ValueError(f"coords must be 'camera', 'world', 'table' or 'image', got {coords!r}")
        min_visible = positive_int(min_visible, "min_visible", minimum=0)
        out = []
        for f in self.frames:
            d = {}
            for k, T in f.gt_poses.items():
                if f.visible[k] < min_visible:
                    continue
                c = T[:3, 3]
                if coords == "camera":
                    d[k] = c.copy()
                elif coords == "image":
                    d[k] = project(c[None], self.camera)[0]
                else:
                    w = self.camera_pose[:3, :3] @ c + self.camera_pose[:3, 3]
                    d[k] = w if coords == "world" else w[:2]
            out.append(d)
        return out


def make_scene(
    n_objects: int = 3,
    n_frames: int = 30,
    image_size: tuple[int, int] = (240, 320),
    dt: float = 0.1,
    noise: float = 0.002,
    seed: int | None = 0,
    **options,
) -> Scene:
    r"""Render a synthetic RGB-D sequence of rigid objects moving on a table.

    The camera (focal length :math:`0.9\,W` px, principal point at the image centre) sits 0.65 m
    above the table and looks down at about 40°; a back wall closes the view, so every pixel has a
    valid depth. Objects (boxes and upright cylinders, 6–16 cm) translate on slightly curved paths
    at ``speed`` m/s and spin about the vertical axis; they never collide and stay in view.

    Parameters
    ----------
    n_objects : int, >= 0
        Number K of moving objects (ids 1..K).
    n_frames : int, >= 1
    image_size : (int, int)
        ``(H, W)`` in pixels, each >= 8.
    dt : float, > 0
        Frame interval in seconds.
    noise : float, >= 0
        Standard deviation (m) of the Gaussian noise added to the depth Z (and the points).
    seed : int or None
        Everything (shapes, colours, motions, noise) is a deterministic function of the seed.
    **options
        ``scenario`` : ``"default"`` (random motions), ``"crossing"`` (objects 1 and 2 move in
        opposite directions at different distances from the camera, so their images cross and 1
        passes in front of 2 around the middle of the sequence; needs ``n_objects >= 2``) or
        ``"occlusion"`` (a static tall box, label 0, hides object 1 completely for a few frames
        in the middle; needs ``n_objects >= 1``) or ``"mixed"`` (both at once, the demo's scene:
        objects 1 and 2 cross as in ``"crossing"`` on shorter paths, object 3 slides behind a
        static box on the right and is hidden for a few frames just after the middle; needs
        ``n_objects >= 3``) or ``"turning"`` (object 1, a cylinder, goes around a circular arc of
        radius 0.13 m at 1 rad/s, turning with it: :class:`ArcTrajectory`; needs
        ``n_objects >= 1``). Remaining objects move randomly.
        ``shapes`` : sequence of ``"box"``/``"cylinder"`` per object (default: alternate, random
        start). ``speed`` : ``(low, high)`` translation speed range in m/s (default (0.06, 0.15)).
        ``max_angular_speed`` : rad/s (default 0.8). ``bend`` : maximal lateral bulge of a path
        in m (default 0.08). ``wall`` : add the back wall (default True). ``texture`` : checker
        textures on table and objects (default True), so optical flow has something to track.

    Returns
    -------
    Scene
        ``scene.frames[i]`` holds ``depth``, ``rgb``, ``points``, ``labels``, ``gt_flow``,
        ``gt_poses``, ``visible``, ``pixels`` ... (see :class:`Frame`).

    Raises
    ------
    ValueError, TypeError
        Bad arguments (the message names the argument).
    RuntimeError
        The objects do not fit: no non-colliding paths in the workspace after repeated placement
        rounds (about 6 objects at the default speeds and 24 frames is where this starts).

    Examples
    --------
    >>> scene = make_scene(n_objects=2, n_frames=2, image_size=(48, 64), noise=0.0, seed=1)
    >>> f = scene.frames[0]
    >>> f.depth.shape, f.rgb.dtype, f.points.shape == (48 * 64, 3)
    ((48, 64), dtype('uint8'), True)
    >>> sorted(set(f.labels.tolist())) == [0, 1, 2] and sorted(f.gt_poses) == [1, 2]
    True
    >>> X, v, k = f.points, f.gt_flow, f.labels
    >>> T0, T1 = f.gt_poses[1], scene.frames[1].gt_poses[1]
    >>> Y = (X[k == 1] + v[k == 1] * scene.dt) @ T1[:3, :3] - T1[:3, 3] @ T1[:3, :3]
    >>> Z = X[k == 1] @ T0[:3, :3] - T0[:3, 3] @ T0[:3, :3]   # same material point, object frame
    >>> bool(np.allclose(Y, Z, atol=1e-12))
    True
    """
    n_objects = positive_int(n_objects, "n_objects", minimum=0)
    n_frames = positive_int(n_frames, "n_frames", minimum=1)
    if isinstance(image_size, (str, bytes)) or not isinstance(image_size, Sequence) or len(image_size) != 2:
        raise ValueError(f"image_size must be a pair (H, W), got {image_size!r}")
    H = positive_int(image_size[0], "image_size[0]", minimum=8)
    W = positive_int(image_size[1], "image_size[1]", minimum=8)
    dt = positive(dt, "dt")
    noise = nonnegative(noise, "noise")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, numbers.Integral)):
        raise TypeError(f"seed must be an int or None, got {type(seed).__name__}")
    opts = parse_options(options)
    scenario = opts["scenario"]
    needed = SCENARIO_MIN_OBJECTS.get(scenario, 0)
    if n_objects < needed:
        raise ValueError(f"n_objects must be >= {needed} for scenario={scenario!r}, got {n_objects}")

    rng = np.random.default_rng(seed)
    noise_rng = np.random.default_rng(rng.integers(2**63))
    cam, T_wc = default_camera((H, W))
    T_cw = np.linalg.inv(T_wc)
    duration = n_frames * dt  # the motion is defined up to t_n (flow of the last frame)
    times = np.linspace(0.0, duration, 4 * n_frames + 1)

    # shapes
    shapes_opt = opts["shapes"]
    if shapes_opt is None:
        start = int(rng.integers(2))
        kinds = [("box", "cylinder")[(start + i) % 2] for i in range(n_objects)]
    else:
        if isinstance(shapes_opt, str) or len(shapes_opt) != n_objects:
            raise ValueError(f"shapes must be a sequence of {n_objects} 'box'/'cylinder', got {shapes_opt!r}")
        kinds = list(shapes_opt)
        for s in kinds:
            if s not in ("box", "cylinder"):
                raise ValueError(f"shapes entries must be 'box' or 'cylinder', got {s!r}")
    objects = {k + 1: random_shape(rng, kinds[k]) for k in range(n_objects)}
    palette_order = rng.permutation(len(PALETTE))
    colors = {k: PALETTE[palette_order[(k - 1) % len(PALETTE)]].copy() for k in objects}

    # static bodies: table, wall, occluder
    tex = 1.0 if opts["texture"] else 0.0  # texture cell sizes are multiplied by this
    static_bodies = [Body(Plane(), T_cw.copy(), 0, (185.0, 160.0, 120.0), 0.05 * tex)]
    if opts["wall"]:
        T_ww = np.eye(4)  # wall frame: z towards the camera (-y world), origin at y = 1.0
        T_ww[:3, :3] = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
        T_ww[:3, 3] = [0.0, 1.0, 0.0]
        static_bodies.append(Body(Plane(), T_cw @ T_ww, 0, (150.0, 170.0, 190.0), 0.1 * tex))
    # scripted objects (straight paths, random spin) replace the first random shapes; the rest move randomly
    paths, occluder = scenario_script(scenario, kinds)
    static_discs = []
    if occluder is not None:
        body, disc = static_occluder(*occluder, T_cw, duration, tex)
        static_bodies.append(body)
        static_discs = [disc]
    trajectories: dict[int, PlanarTrajectory] = {}
    placed = []
    for k, (shape, *path) in paths.items():
        objects[k] = shape
        # a scripted path is (start, end) of a straight path, or a trajectory of its own (an arc)
        if len(path) == 1:
            trajectories[k] = path[0]
        else:
            trajectories[k] = straight_trajectory(rng, *path, duration, shape, opts)
        placed.append((trajectories[k], shape.radius))
    trajectories.update(random_trajectories(rng, objects, trajectories, duration, opts, placed, times,
                                             static_discs))

    light_c = T_cw[:3, :3] @ LIGHT_W
    dirs = ray_directions(cam).reshape(H, W, 3)
    static_rc = empty_cast(H, W)
    cast_into(static_rc, cam, dirs, static_bodies, 0)
    static_rgb = shade(static_rc, static_bodies, light_c).reshape(H, W, 3)
    n_static = len(static_bodies)
    frames = []
    # object-to-camera poses at t_0 .. t_n (frame i moves from pose i to pose i + 1)
    all_poses = [{k: T_cw @ trajectories[k].pose(i * dt) for k in objects} for i in range(n_frames + 1)]
    for i in range(n_frames):
        t0 = i * dt
        poses, poses_next = all_poses[i], all_poses[i + 1]
        moving = [
            Body(objects[k], poses[k], k, tuple(colors[k]), 0.02 if opts["texture"] else 0.0) for k in objects
        ]
        rc = copy_cast(static_rc)
        cast_into(rc, cam, dirs, moving, n_static)
        bodies = list(static_bodies) + moving
        on_obj = rc.body >= n_static
        rgb = static_rgb.copy()
        rgb[on_obj] = shade(rc, bodies, light_c, on_obj)
        valid = rc.depth > 0
        depth_gt = rc.depth
        depth = depth_gt.copy()
        if noise > 0:
            depth[valid] += noise_rng.normal(0.0, noise, int(valid.sum()))
            depth[valid] = np.maximum(depth[valid], 1e-6)
        points = backproject(depth, cam)[valid]
        X = backproject(depth_gt, cam)[valid]
        labels = rc.label[valid].astype(np.int64)
        flow = np.zeros_like(X)
        for k in objects:
            m = labels == k
            if m.any():
                M = poses_next[k] @ np.linalg.inv(poses[k])
                flow[m] = (apply_transform(M, X[m]) - X[m]) / dt
        visible = {k: int(np.count_nonzero(rc.label == k)) for k in objects}
        frames.append(
            Frame(
                index=i,
                time=t0,
                depth=depth,
                depth_gt=depth_gt,
                rgb=rgb,
                label_image=rc.label,
                points=points,
                labels=labels,
                gt_flow=flow,
                gt_poses=poses,
                visible=visible,
                _camera=cam,
                _gt_points=X,
            )
        )
    return Scene(
        camera=cam,
        dt=dt,
        frames=frames,
        camera_pose=T_wc,
        objects=objects,
        trajectories=trajectories,
        static_bodies=static_bodies,
        colors=colors,
        scenario=scenario,
    )
