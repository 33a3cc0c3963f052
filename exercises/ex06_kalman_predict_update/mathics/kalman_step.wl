(* Exercise kalman_step (Mathematica, run on Mathics3): one Kalman filter step.
   kalmanStep[x, P, F, Q, H, R, z] predicts with F, Q, then updates with the measurement z, and
   returns {x, P} after the step (x a vector of n entries, P n x n). *)
kalmanStep[x0_, P0_, F_, Q_, H_, R_, z_] := Module[{x = x0, P = P0, S, K, ikh},
  (* BEGIN SOLUTION *)
  x = F . x;
  P = F . P . Transpose[F] + Q;
  S = H . P . Transpose[H] + R;
  K = P . Transpose[H] . Inverse[S];
  x = x + K . (z - H . x);
  ikh = IdentityMatrix[Length[x]] - K . H;
  P = ikh . P . Transpose[ikh] + K . R . Transpose[K];  (* Joseph form *)
  (* END SOLUTION *)
  {x, P}]
