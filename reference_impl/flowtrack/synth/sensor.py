r"""Kinect-like depth artefacts for a rendered depth image (structured-light RGB-D sensors).

A rendered depth image is exact up to the Gaussian noise :func:`flowtrack.synth.make_scene` adds. A
structured-light sensor (Kinect v1, PrimeSense, the TUM RGB-D benchmark's camera) differs in four
ways that matter for a tracker, each an option of :func:`kinect_depth`:

- **depth-dependent noise** (``noise``): the axial standard deviation grows with the square of the
  distance, :math:`\sigma_z(Z) = 0.0012 + 0.0019\,(Z - 0.4)^2` m (Nguyen, Izadi and Lovell, *Modeling
  Kinect sensor noise for improved 3D reconstruction and tracking*, 3DIMPVT 2012). The image already
  carries ``noise_floor`` (the scene's own noise), so only the difference of variances,
  :math:`\sigma_z^2 - \sigma_0^2` (when positive), is added.
- **disparity quantisation** (``quantise``): the sensor measures disparity :math:`d = f b / Z` in
  steps of 1/8 px (Khoshelham and Elberink 2012), so depth takes the values :math:`k / \mathrm{round}(k/Z)`,
  :math:`k = 8 f b`, with the sensor's :math:`f` = 580 px (its 640 px wide IR image, whatever size
  the depth is rendered at) and baseline :math:`b` = 7.5 cm: steps of :math:`Z^2 / k` (2.9 mm at
  1 m, 11 mm at 2 m).
- **flying pixels** (``flying_pixels``): across a depth jump (> ``edge_jump`` between neighbours), the
  pixel on either side is, with probability 1/2, replaced by a random mix :math:`\alpha Z_a + (1 -
  \alpha) Z_b`, :math:`\alpha \sim U(0, 1)` of the two depths — a point floating between foreground and
  background, as the sensor's correlation window straddles the edge.
- **edge holes** (``edge_holes``): pixels on a depth edge (gradient of the *input* depth above
  ``edge_gradient`` per pixel) are dropped (depth 0) with probability ``edge_drop``.

The artefacts are applied in that order. Pixels without depth (0) stay 0.

Examples
--------
>>> import numpy as np
>>> depth = np.full((4, 6), 1.0)
>>> depth[:, 3:] = 2.0                      # a depth jump between columns 2 and 3
>>> out = kinect_depth(depth, np.random.default_rng(0), noise=False, flying_pixels=False,
...                    edge_holes=False)
>>> k = 8 * 580 * 0.075                     # depth is quantised in disparity steps of 1/8 px
>>> bool(np.allclose(out, k / np.round(k / depth)))
True
>>> float(np.abs(out - depth).max()) < 0.011 / 2 + 1e-12   # half a step at 2 m
True
"""

from __future__ import annotations

import numpy as np

from .._validation import as_array, nonnegative, positive

__all__ = ["kinect_depth", "kinect_sigma"]

KINECT_FOCAL_640 = 580.0  #: Kinect v1 depth focal length (px) at 640 px image width
KINECT_BASELINE = 0.075  #: Kinect v1 projector-camera baseline (m)
KINECT_SUBPIXEL = 8  #: disparity steps per pixel


def kinect_sigma(Z):
    r"""Axial depth noise of a Kinect v1, :math:`\sigma_z = 0.0012 + 0.0019 (Z - 0.4)^2` m (Nguyen 2012).

    Examples
    --------
    >>> round(float(kinect_sigma(1.0)), 6), round(float(kinect_sigma(2.0)), 6)
    (0.001884, 0.006064)
    """
    Z = np.asarray(Z, dtype=float)
    return 0.0012 + 0.0019 * (Z - 0.4) ** 2


def kinect_depth(depth, rng, *, noise=True, quantise=True, flying_pixels=True, edge_holes=True,
                 noise_floor=0.002, edge_jump=0.04, edge_gradient=0.02, edge_drop=0.3):
    r"""A depth image with Kinect-like artefacts (see the module docstring for the model of each).

    Parameters
    ----------
    depth : array_like, shape (H, W)
        Depth in metres; 0 marks pixels without a measurement (kept at 0).
    rng : numpy.random.Generator
    noise, quantise, flying_pixels, edge_holes : bool
        Which artefacts to apply (all by default).
    noise_floor : float
        Standard deviation (m) of the noise ``depth`` already carries (the synthetic scene's
        ``noise``, 2 mm in the demo); only :math:`\sqrt{\sigma_z^2 - \sigma_0^2}` is added.
    edge_jump : float
        Depth difference (m) between neighbours that makes a flying-pixel candidate.
    edge_gradient : float
        Depth gradient (m per pixel, ``numpy.gradient`` of the input) above which a pixel is on an edge.
    edge_drop : float
        Probability that an edge pixel is dropped.

    Returns
    -------
    numpy.ndarray, shape (H, W)

    Raises
    ------
    ValueError
        ``depth`` not 2-D or with NaN/inf, or a parameter out of range.
    """
    Z0 = as_array(depth, "depth")
    if Z0.ndim != 2:
        raise ValueError(f"depth must be an (H, W) image, got shape {Z0.shape}")
    noise_floor = nonnegative(noise_floor, "noise_floor")
    edge_jump = positive(edge_jump, "edge_jump")
    edge_gradient = positive(edge_gradient, "edge_gradient")
    edge_drop = float(edge_drop)
    if not 0.0 <= edge_drop <= 1.0:
        raise ValueError(f"edge_drop must be in [0, 1], got {edge_drop}")
    valid = Z0 > 0
    Z = Z0.copy()
    if noise:
        extra = np.sqrt(np.maximum(kinect_sigma(Z) ** 2 - noise_floor**2, 0.0))
        Z = Z + rng.normal(0.0, 1.0, Z.shape) * extra
    if quantise:
        k = KINECT_SUBPIXEL * KINECT_FOCAL_640 * KINECT_BASELINE
        Z = np.where(valid, k / np.maximum(np.round(k / np.where(valid, Z, 1.0)), 1.0), 0.0)
    if flying_pixels:
        for axis in (0, 1):
            a = Z
            b = np.roll(Z, -1, axis=axis)  # the next pixel along the axis
            jump = (np.abs(a - b) > edge_jump) & valid & np.roll(valid, -1, axis=axis)
            if axis == 0:
                jump[-1] = False
            else:
                jump[:, -1] = False
            far_is_a = a > b
            alpha = rng.uniform(0.0, 1.0, Z.shape)
            # the far pixel of a pair takes a mix of both depths ...
            sel = jump & far_is_a & (rng.uniform(size=Z.shape) < 0.5)
            Z = np.where(sel, alpha * a + (1.0 - alpha) * b, Z)
            # ... or the far pixel being the next one, it mixes with this one
            selb = np.roll(jump & ~far_is_a & (rng.uniform(size=Z.shape) < 0.5), 1, axis=axis)
            Z = np.where(selb, alpha * np.roll(a, 1, axis=axis) + (1.0 - alpha) * Z, Z)
    if edge_holes:
        gy, gx = np.gradient(Z0)
        edge = np.hypot(gx, gy) > edge_gradient
        Z = np.where(edge & (rng.uniform(size=Z.shape) < edge_drop), 0.0, Z)
    return np.where(valid, Z, 0.0)
