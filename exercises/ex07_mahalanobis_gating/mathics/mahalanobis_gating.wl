(* Exercise mahalanobis_gating (Mathematica, run on Mathics3): squared Mahalanobis distances of the
   detections Z (a list of N vectors) to the predicted measurement zPred with innovation covariance
   S, and the gate: mahalanobisGating[zPred, S, Z, gate] returns {d2, inside} with
   d2[[j]] = (Z[[j]] - zPred) . Inverse[S] . (Z[[j]] - zPred) and inside[[j]] = 1 if d2[[j]] <= gate,
   else 0. *)
mahalanobisGating[zPred_, S_, Z_, gate_] := Module[
  {d2 = ConstantArray[0, Length[Z]], inside = ConstantArray[0, Length[Z]], si},
  (* BEGIN SOLUTION *)
  si = Inverse[S];
  d2 = Table[(z - zPred) . si . (z - zPred), {z, Z}];
  inside = Table[If[d <= gate, 1, 0], {d, d2}];
  (* END SOLUTION *)
  {d2, inside}]
