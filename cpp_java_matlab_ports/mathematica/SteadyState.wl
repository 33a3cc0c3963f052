(* ::Package:: *)
(* Steady-state covariance of the scalar Kalman filter, solved symbolically.
   Model x_t = f x_{t-1} + w, z_t = h x_t + v, Var w = q, Var v = r. The predicted variance
   P satisfies the scalar discrete Riccati equation
       P == f^2 P - f^2 P^2 h^2/(h^2 P + r) + q,
   a quadratic h^2 P^2 + (r (1 - f^2) - q h^2) P - q r == 0 with one positive root (q, r > 0). *)

riccatiRoots = p /. Solve[p == f^2 p - f^2 p^2 h^2/(h^2 p + r) + q, p];

(* The symbolic positive root for q, r > 0, h != 0: the root that is positive at a sample point
   (the product of the roots is -q r/h^2 < 0, so exactly one root is positive everywhere). *)
steadyStateSymbolic = Select[riccatiRoots,
  (# /. {f -> 1, h -> 1, q -> 1, r -> 1}) > 0 &][[1]];

(* Predicted and posterior steady-state variance at numeric f, h, q, r. The inputs are made exact
   (Rationalize[#, 0]) so the closed form is evaluated without cancellation, then N. *)
steadyStateP[fv_, hv_, qv_, rv_] := Module[{rules, P},
  rules = Thread[{f, h, q, r} -> Map[Rationalize[#, 0] &, {fv, hv, qv, rv}]];
  P = steadyStateSymbolic /. rules;
  N[{P, P - P^2 h^2/(h^2 P + r) /. rules}, 30]]
