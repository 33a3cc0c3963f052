"""The mistake catalogue: stable ids of the wrong answers students give, and what to tell them.

Each entry names the mistake, says why it is wrong and points to the lesson section that explains
it. The ids are stable (instructors' reports count them across terms: ``misconceptions.csv``, the
class report); a new mistake gets a new id, an id is never reused for another mistake. Which
exercise recognises which id, and from what, is defined next to the exercise's tests (its
``Variant``\\ s); the generic ids apply to any array result.

The feedback line is ``mistake <id>: <message>`` (a contract, see ``/work/shared/API.md``).

>>> mistake_line("generic-sign").startswith("mistake generic-sign: ")
True
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["CATALOGUE", "GENERIC", "OTHER_LANGUAGES", "Mistake", "mistake_line"]


@dataclass(frozen=True)
class Mistake:
    """A catalogued mistake: ``id``, ``message`` (what, why, where in the lessons) and its exercise."""

    id: str
    exercise: str
    message: str


_L1 = "lesson 01_camera_geometry"
_L2 = "lesson 02_variational_scene_flow"
_L3 = "lesson 03_graph_scene_flow"
_L4 = "lesson 04_bayes_and_kalman"
_L5 = "lesson 05_multi_object_tracking"
_L6 = "lesson 06_flow_to_tracks"

_ENTRIES = [
    # ex01 ------------------------------------------------------------------------------------------
    Mistake(
        "jacobian-sign",
        "ex01_projection_jacobian",
        "the d/dZ entries have the wrong sign: x = fx X/Z + cx decreases as Z grows, so dx/dZ = "
        f"-fx X/Z^2 (and dy/dZ = -fy Y/Z^2); see {_L1} §2",
    ),
    Mistake(
        "jacobian-fx-fy-swapped",
        "ex01_projection_jacobian",
        "fx and fy are swapped: the image x coordinate scales with fx and y with fy, so row 0 of "
        f"the Jacobian carries fx and row 1 fy (they differ on real cameras); see {_L1} §1-2",
    ),
    Mistake(
        "jacobian-z-not-squared",
        "ex01_projection_jacobian",
        f"the d/dZ entries divide by Z instead of Z^2: d(X/Z)/dZ = -X/Z^2 (quotient rule); see {_L1} §2",
    ),
    Mistake(
        "projection-missing-principal-point",
        "ex01_projection_jacobian",
        "the principal point is missing: pixel coordinates are fx X/Z + cx and fy Y/Z + cy, "
        f"(cx, cy) moves the origin to the image corner; see {_L1} §1",
    ),
    # ex02 ------------------------------------------------------------------------------------------
    Mistake(
        "missing-dt",
        "ex02_optical_flow",
        "the time step is missing: J(X) v is a pixel velocity (px/s); the flow between two frames "
        f"is the displacement u = J(X) v dt; see {_L1} §3",
    ),
    Mistake(
        "flow-ignores-depth-motion",
        "ex02_optical_flow",
        "motion along Z is ignored: the Jacobian's third column -f X/Z^2 turns approaching or "
        f"receding into image motion (expansion), u = J(X) v dt uses all of v; see {_L1} §3",
    ),
    # ex03 ------------------------------------------------------------------------------------------
    Mistake(
        "jacobi-not-gauss-seidel",
        "ex03_gauss_seidel",
        "this is a Jacobi sweep: every pixel is updated from the old iterate. In red-black "
        "Gauss-Seidel the black pixels use the red values just computed in the same sweep (which "
        f"is why it converges about twice as fast); see {_L2} §4",
    ),
    Mistake(
        "black-before-red",
        "ex03_gauss_seidel",
        "black pixels are updated before red ones: the sweep must update the red pixels (i + j "
        f"even) first, then the black ones from the new red values; see {_L2} §4",
    ),
    Mistake(
        "dense-solve-not-sweeps",
        "ex03_gauss_seidel",
        "the result does not come from red-black sweeps: after max_sweeps sweeps the iterate is "
        "still far from the solution, yours is the exact solution of a direct solve. The exercise "
        f"is the iteration (a dense solve needs O(N^2) memory on an image); see {_L2} §4",
    ),
    Mistake(
        "residual-rate-not-gauss-seidel",
        "ex03_gauss_seidel",
        "the residual does not shrink at the red-black Gauss-Seidel rate: one sweep multiplies it by "
        "about rho(G_GS) = rho(G_Jacobi)^2 on the model problem, yours by another factor, so each "
        "sweep is not one Gauss-Seidel sweep (over- or under-relaxed updates, a sweep counted "
        f"twice or skipped, pixels updated from stale values); see {_L2} §5",
    ),
    Mistake(
        "neumann-boundary-degree",
        "ex03_gauss_seidel",
        "every pixel is given 4 neighbours: with the Neumann boundary a border pixel has 3 and a "
        f"corner 2 (deg_p counts only the neighbours inside the grid); see {_L2} §3",
    ),
    # ex04 ------------------------------------------------------------------------------------------
    Mistake(
        "knn-not-symmetrised",
        "ex04_graph_scene_flow",
        "the kNN graph is not symmetrised: j being among the k nearest of i does not make i one of "
        f"j's; the graph keeps an edge when either holds, so W and L are symmetric; see {_L3} §1",
    ),
    Mistake(
        "affinity-sigma-not-squared",
        "ex04_graph_scene_flow",
        f"the affinity divides by sigma instead of sigma^2: w_ij = exp(-|X_i - X_j|^2 / sigma^2); see {_L3} §1",
    ),
    # ex05 ------------------------------------------------------------------------------------------
    Mistake(
        "q-block-diagonal",
        "ex05_cv_model",
        "Q is block-diagonal blkdiag(Q1d, Q1d), which fits the state order [px, vx, py, vy]; for "
        "[px, py, vx, vy] each Q1d entry couples a position with its own velocity: Q = Q1d kron I2 "
        f"(the syllabus listings' bug); see {_L4} §3",
    ),
    Mistake(
        "q-continuous-white-noise",
        "ex05_cv_model",
        "this is the continuous white-noise model (dt^3/3, dt^2/2, dt); the exercise asks for the "
        "discrete white-noise acceleration Q = q G G^T with G = [dt^2/2, dt] (dt^4/4, dt^3/2, dt^2); "
        f"see {_L4} §3",
    ),
    Mistake(
        "q-missing-q",
        "ex05_cv_model",
        f"Q is not scaled by the acceleration variance q (Q = q G G^T); see {_L4} §3",
    ),
    # ex06 ------------------------------------------------------------------------------------------
    Mistake(
        "innovation-without-R",
        "ex06_kalman_predict_update",
        "the innovation covariance lacks R: S = H P H^T + R, the measurement noise adds to the "
        f"predicted spread (without it the filter trusts the measurement too much); see {_L4} §4",
    ),
    Mistake(
        "predict-without-Q",
        "ex06_kalman_predict_update",
        "the predicted covariance lacks Q: P = F P F^T + Q, the process noise is what keeps the "
        f"filter from becoming over-confident; see {_L4} §2 and §6",
    ),
    # ex07 ------------------------------------------------------------------------------------------
    Mistake(
        "euclidean-not-mahalanobis",
        "ex07_mahalanobis_gating",
        "this is the squared Euclidean distance: the Mahalanobis cost weighs the difference by "
        f"S^-1, d^T S^-1 d, so an uncertain track accepts farther detections; see {_L5} §1",
    ),
    Mistake(
        "covariance-not-inverted",
        "ex07_mahalanobis_gating",
        "S is used instead of its inverse: d^T S d grows with the uncertainty instead of "
        f"shrinking; the cost is d^T S^-1 d (solve with S, or its Cholesky factor); see {_L5} §1",
    ),
    Mistake(
        "distance-not-squared",
        "ex07_mahalanobis_gating",
        "this is the Mahalanobis distance, not its square: the chi-square gate applies to "
        f"d^T S^-1 d, which is chi-square distributed with m degrees of freedom; see {_L5} §1",
    ),
    Mistake(
        "gate-wrong-dof",
        "ex07_mahalanobis_gating",
        "the gate uses the wrong degrees of freedom: d^T S^-1 d is chi-square with m = the "
        f"measurement dimension (z_pred.shape[1]) degrees of freedom; see {_L5} §1 and §3",
    ),
    Mistake(
        "gate-prob-as-threshold",
        "ex07_mahalanobis_gating",
        "the gate probability is used as the threshold: the threshold is the chi-square "
        f"quantile chi2.ppf(prob, m), not prob itself; see {_L5} §1",
    ),
    # ex08 ------------------------------------------------------------------------------------------
    Mistake(
        "greedy-assignment",
        "ex08_hungarian",
        "this is a greedy assignment (cheapest pair first): it is not optimal when a cheap pair "
        "blocks two others; the Hungarian algorithm finds the minimum total cost; see "
        f"{_L5} §2",
    ),
    Mistake(
        "assignment-maximises",
        "ex08_hungarian",
        f"the assignment maximises the total cost instead of minimising it; see {_L5} §2",
    ),
    Mistake(
        "brute-force-assignment",
        "ex08_hungarian",
        "right on small matrices but out of time on larger ones: trying every permutation costs "
        f"n! (10! = 3.6 million); the Hungarian algorithm is O(n^3); see {_L5} §2",
    ),
    # ex09 ------------------------------------------------------------------------------------------
    Mistake(
        "deletion-off-by-one",
        "ex09_track_management",
        "a confirmed track is deleted one frame early: it survives max_misses consecutive misses "
        f"and is deleted at miss max_misses + 1; see {_L5} §4",
    ),
    Mistake(
        "confirmation-off-by-one",
        "ex09_track_management",
        "a track is confirmed one hit late: it is confirmed once it has min_hits hits (the birth "
        f"counts as the first); see {_L5} §4",
    ),
    Mistake(
        "tentative-track-coasts",
        "ex09_track_management",
        "a tentative track survives a miss: only confirmed tracks coast; a tentative track missed "
        f"once is deleted (most false alarms are never seen twice); see {_L5} §4",
    ),
    Mistake(
        "track-id-reused",
        "ex09_track_management",
        "a track id is reused: every new track gets the next unused id, even for an object seen "
        f"before (a reused id would merge two tracks in the metrics); see {_L5} §4-5",
    ),
    # ex10 ------------------------------------------------------------------------------------------
    Mistake(
        "clusters-by-position-only",
        "ex10_motion_clustering",
        "points are joined by position only: two touching objects moving differently must be "
        f"separated by their velocities (|v_i - v_j| <= sigma_v); see {_L6} §1-2",
    ),
    Mistake(
        "static-points-kept",
        "ex10_motion_clustering",
        "the static background is kept: points slower than min_speed are not moving objects and "
        f"are dropped before clustering; see {_L6} §2-3",
    ),
    # ex11 ------------------------------------------------------------------------------------------
    Mistake(
        "q-kron-for-this-order",
        "ex11_concepts",
        "this is Q1d kron I2, the Q of the order [px, py, vx, vy]; with [px, vx, py, vy] each "
        f"position sits next to its own velocity, so Q = blkdiag(Q1d, Q1d); see {_L4} §3",
    ),
    Mistake(
        "el-laplacian-sign",
        "ex11_concepts",
        "the smoothness term has the wrong sign: integrating 2 lam grad v . grad(dv) by parts gives "
        f"-2 lam Lap(v) dv, so the equation is dt (a + v dt - b) - lam Lap(v) = 0; see {_L2} §2",
    ),
    Mistake(
        "el-missing-inner-derivative",
        "ex11_concepts",
        "the inner derivative dt is missing: d/dv (a + v dt - b)^2 = 2 dt (a + v dt - b) (chain "
        f"rule); see {_L2} §2",
    ),
    Mistake(
        "el-half-factor",
        "ex11_concepts",
        "the two terms are scaled differently: both squares give a factor 2 (2 dt (a + v dt - b) "
        f"and -2 lam Lap(v)), which cancel together, not one of them alone; see {_L2} §2",
    ),
    Mistake(
        "inverse-depth-sign",
        "ex11_concepts",
        f"d(1/Z)/dZ = -1/Z^2: the inverse depth decreases as Z grows; see {_L1} §2",
    ),
    Mistake(
        "null-space-assumed-px-vx-order",
        "ex11_concepts",
        "these are the combinations the right Q cannot excite (2 p - dt v for each axis); the "
        "listings use blkdiag(Q1d, Q1d) with the state [px, py, vx, vy], which couples px with py "
        f"and vx with vy, so what it cannot excite is 2 px - dt py and 2 vx - dt vy; see {_L4} §3",
    ),
    Mistake(
        "most-excited-not-unexcited",
        "ex11_concepts",
        "these are the directions Q excites (its range); the question asks for its null space, "
        f"the combinations x with Q x = 0; see {_L4} §3",
    ),
    Mistake(
        "nees-inverted",
        "ex11_concepts",
        "the ratio is inverted: NEES = e^T P^-1 e, the actual squared error measured in the "
        "filter's claimed covariance, so its expectation is (actual variance) / P, above 1 for "
        f"an over-confident filter; see {_L4} §8",
    ),
    Mistake(
        "nees-assumed-consistent",
        "ex11_concepts",
        "the expected NEES is the state dimension only when the filter's model is right; with "
        f"q_filter != q_true it is not; see {_L4} §8",
    ),
    Mistake(
        "nees-prior-covariance",
        "ex11_concepts",
        "this uses the predicted (prior) error and covariance; the question asks for the NEES of "
        f"the posterior (after the update); see {_L4} §8",
    ),
    Mistake(
        "lambda-largest",
        "ex11_concepts",
        "the largest λ of the sweep over-smooths: it flattens the motion the data show; choose "
        f"the λ with the smallest error against the ground truth; see {_L2} §6",
    ),
    Mistake(
        "lambda-smallest",
        "ex11_concepts",
        "the smallest λ (or 0) fits the noise: it minimises the data term, not the error against "
        f"the ground truth; see {_L2} §6",
    ),
    Mistake("lambda-log10", "ex11_concepts", f"this looks like log10(λ): give λ itself; see {_L2} §6"),
]

# recognised only in answers in other languages (flowtrack_course.polyglot.problems), where one
# function does a whole filter step or takes the intrinsics as arguments; ``exercise`` is the problem
OTHER_LANGUAGES = [
    Mistake(
        "kalman-no-predict",
        "kalman_step",
        "the update starts from x and P as they were: a step first predicts them (x = F x, "
        f"P = F P F^T + Q), then updates the prediction with z; see {_L4} §2 and §4",
    ),
    Mistake(
        "kalman-prior-cov",
        "kalman_step",
        "P is the predicted covariance F P F^T + Q: the update must shrink it, P = (I - K H) P "
        f"(the measurement adds information); see {_L4} §4",
    ),
    Mistake(
        "jacobian-no-focal",
        "projection_jacobian",
        "the focal lengths are missing: u = fx X/Z + cx and v = fy Y/Z + cy, so row 0 of the Jacobian "
        f"carries fx and row 1 fy; see {_L1} §1-2",
    ),
]

GENERIC = [
    Mistake(
        "generic-sign",
        "*",
        "your result is the expected one with the sign flipped: look for a subtraction done "
        "the wrong way round or a minus sign lost in a derivative",
    ),
    Mistake(
        "generic-scale",
        "*",
        "your result is the expected one times a constant factor: look for a missing or extra "
        "factor (a time step, a 2 or 1/2, a gain or a variance)",
    ),
    Mistake(
        "generic-transpose",
        "*",
        "your result is the transpose of the expected one: check which index is the row (the "
        "docstring gives the shape and the meaning of each axis)",
    ),
    Mistake(
        "generic-permutation",
        "*",
        "your result has the expected rows or columns in another order: check the order the "
        "docstring asks for (state order, sorting, indices)",
    ),
]

CATALOGUE: dict[str, Mistake] = {m.id: m for m in _ENTRIES + OTHER_LANGUAGES + GENERIC}


def mistake_line(mistake_id: str) -> str:
    """The feedback line of a catalogued mistake: ``mistake <id>: <message>``."""
    return f"mistake {mistake_id}: {CATALOGUE[mistake_id].message}"
