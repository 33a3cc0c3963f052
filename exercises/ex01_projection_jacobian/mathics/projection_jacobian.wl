(* Exercise projection_jacobian (Mathematica, run on Mathics3): the Jacobian d(u, v)/d(X, Y, Z)
   (2 x 3) of the pinhole projection u = fx X/Z + cx, v = fy Y/Z + cy at the point X = {X, Y, Z}. *)
projectionJacobian[X_, fx_, fy_, cx_, cy_] := Module[{J = ConstantArray[0, {2, 3}]},
  (* BEGIN SOLUTION *)
  J = {{fx/X[[3]], 0, -fx X[[1]]/X[[3]]^2}, {0, fy/X[[3]], -fy X[[2]]/X[[3]]^2}};
  (* END SOLUTION *)
  J]
