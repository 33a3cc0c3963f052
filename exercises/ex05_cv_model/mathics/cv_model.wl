(* Exercise cv_model (Mathematica, run on Mathics3): the constant-velocity model of a 2-D point,
   state {px, py, vx, vy}.
   cvModel[dt, q] returns {F, Q}: F (4 x 4) moves the state by dt; Q (4 x 4) is the noise of a white
   acceleration of variance q on each axis, constant over a step. On one axis, with the state
   {p, v}, it is q Q1d with Q1d = {{dt^4/4, dt^3/2}, {dt^3/2, dt^2}}: place its entries for the state
   order {px, py, vx, vy} (which entries of Q are the (px, vx) pair?). *)
cvModel[dt_, q_] := Module[{F = ConstantArray[0, {4, 4}], Q = ConstantArray[0, {4, 4}]},
  (* BEGIN SOLUTION *)
  F = {{1, 0, dt, 0}, {0, 1, 0, dt}, {0, 0, 1, 0}, {0, 0, 0, 1}};
  Q = q KroneckerProduct[{{dt^4/4, dt^3/2}, {dt^3/2, dt^2}}, IdentityMatrix[2]];
  (* END SOLUTION *)
  {F, Q}]
