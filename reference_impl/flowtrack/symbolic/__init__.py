r"""Symbolic (sympy) derivations of the lesson's formulas.

Every derivation is a function returning sympy objects, built from first principles (differentiate,
integrate, minimise, complete the square), never by typing in the answer. Each has a numeric
counterpart (``*_numeric``) obtained with :func:`sympy.lambdify` from the *derived* expression, so
tests and lessons can compare the derivation with the numerical reference implementation.

- :func:`projection_jacobian` — :math:`\partial\pi/\partial X` of the pinhole projection (§2, Problem 1);
- :func:`euler_lagrange_scene_flow` — :math:`2\Delta t(a + v\Delta t - b) - 2\lambda\Delta v = 0`
  (§3, Problem 2);
- :func:`white_noise_acceleration_Q` — process noise of the constant-velocity model, discrete and
  continuous white-noise acceleration, :math:`Q_{1D} \otimes I_d` for the state ``[p, v]`` (§6);
- :func:`kalman_gain` — :math:`K = PH^\top(HPH^\top + R)^{-1}` as the minimiser of
  :math:`\operatorname{tr} P^+` (§6);
- :func:`kalman_posterior` — Gaussian prior × Gaussian likelihood is Gaussian, with the Kalman
  update's mean and variance (Problem 3);
- :func:`steady_state_variance_scalar` — the positive root of the scalar Riccati equation (§11.2);
- :func:`graph_normal_equations` — :math:`(\Delta t^2 I + \lambda L\otimes I_3)\mathbf v
  = \Delta t\operatorname{vec}(Y - X)` from the gradient of the graph energy (§4, lesson 3), and
  :func:`commutation_matrix` — :math:`\Pi(A\otimes B)\Pi^\top = B\otimes A`, which splits it into
  three :math:`N\times N` systems and relates :math:`Q_{1D}\otimes I_d` to
  :math:`\operatorname{blkdiag}(Q_{1D},\dots)` (:func:`process_noise_orderings`, lessons 4 and 7);
- :func:`rigid_mean_velocity` — the mean velocity of a rigid cluster is the velocity of the body
  point at its centroid (Problem 5, lesson 6);
- :func:`affinity_threshold` — :math:`e^{-\lVert\Delta v\rVert^2/\sigma_v^2} = e^{-m}` at
  :math:`\lVert\Delta v\rVert = \sqrt m\,\sigma_v` (lesson 6);
- :func:`normalized_cut` — :math:`\mathrm{Ncut}(A,B) = y^\top Ly/y^\top Dy` for the two-valued
  indicator (Problem 5);
- :func:`chi2_distribution` — the squared Mahalanobis distance of a Gaussian innovation is
  :math:`\chi^2_m`: CDF, mean m, variance 2m (§7, lesson 5), and the gate that inverts it;
- :func:`assignment_constraints` — the assignment problem's constraint matrix, totally unimodular
  (:func:`is_totally_unimodular`), so its LP relaxation (:func:`assignment_lp_numeric`) is integral
  (Problem 4).

The package mirrors the lessons: :mod:`~flowtrack.symbolic.camera` (lesson 1),
:mod:`~flowtrack.symbolic.variational` and :mod:`~flowtrack.symbolic.rgbd` (2),
:mod:`~flowtrack.symbolic.graph` (3),
:mod:`~flowtrack.symbolic.filtering` (4), :mod:`~flowtrack.symbolic.motion` (6),
:mod:`~flowtrack.symbolic.association` (5),
:mod:`~flowtrack.symbolic.clustering` (6) and :mod:`~flowtrack.symbolic.five_languages` (7); every
name is importable from ``flowtrack.symbolic`` itself.
"""

from __future__ import annotations

from .association import (
    ChiSquare,
    assignment_constraints,
    assignment_count,
    assignment_lp_numeric,
    chi2_cdf_numeric,
    chi2_distribution,
    chi2_gate_closed_form,
    chi2_gate_numeric,
    is_totally_unimodular,
)
from .camera import (
    projection_jacobian,
    projection_jacobian_numeric,
    projection_symbols,
)
from .clustering import (
    NormalizedCut,
    RigidMeanVelocity,
    affinity_threshold,
    affinity_threshold_numeric,
    normalized_cut,
    normalized_cut_numeric,
    rigid_mean_velocity,
    rigid_mean_velocity_numeric,
    rigid_twist_mean_velocity_numeric,
)
from .filtering import (
    kalman_gain,
    kalman_gain_closed_form,
    kalman_gain_numeric,
    kalman_matrices,
    kalman_posterior,
    kalman_posterior_numeric,
    steady_state_variance_scalar,
    steady_state_variance_scalar_numeric,
    white_noise_acceleration_Q,
    white_noise_acceleration_Q_numeric,
)
from .five_languages import (
    process_noise_orderings,
)
from .graph import (
    GraphNormalEquations,
    commutation_matrix,
    graph_normal_equations,
    graph_normal_equations_numeric,
)
from .motion import (
    turn_rate_limits,
    turn_rate_model,
    turn_rate_model_numeric,
)
from .rgbd import (
    pixel_data_term,
    rgbd_energy_density,
    rgbd_euler_lagrange,
)
from .variational import (
    euler_lagrange_scene_flow,
    scene_flow_lagrangian,
)

__all__ = [
    "ChiSquare",
    "GraphNormalEquations",
    "NormalizedCut",
    "RigidMeanVelocity",
    "affinity_threshold",
    "affinity_threshold_numeric",
    "assignment_constraints",
    "assignment_count",
    "assignment_lp_numeric",
    "chi2_cdf_numeric",
    "chi2_distribution",
    "chi2_gate_closed_form",
    "chi2_gate_numeric",
    "commutation_matrix",
    "euler_lagrange_scene_flow",
    "graph_normal_equations",
    "graph_normal_equations_numeric",
    "is_totally_unimodular",
    "kalman_gain",
    "kalman_gain_closed_form",
    "kalman_gain_numeric",
    "kalman_matrices",
    "kalman_posterior",
    "kalman_posterior_numeric",
    "normalized_cut",
    "normalized_cut_numeric",
    "pixel_data_term",
    "process_noise_orderings",
    "projection_jacobian",
    "projection_jacobian_numeric",
    "projection_symbols",
    "rigid_mean_velocity",
    "rigid_mean_velocity_numeric",
    "rigid_twist_mean_velocity_numeric",
    "rgbd_energy_density",
    "rgbd_euler_lagrange",
    "scene_flow_lagrangian",
    "steady_state_variance_scalar",
    "steady_state_variance_scalar_numeric",
    "white_noise_acceleration_Q",
    "turn_rate_limits",
    "turn_rate_model",
    "turn_rate_model_numeric",
    "white_noise_acceleration_Q_numeric",
]
