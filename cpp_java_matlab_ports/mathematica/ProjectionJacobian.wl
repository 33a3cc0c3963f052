(* ::Package:: *)
(* Jacobian of the pinhole projection by symbolic differentiation with D. *)

projection[{x_, y_, z_}, fx_, fy_, cx_, cy_] := {fx x/z + cx, fy y/z + cy};

(* Outer[D, ...] gives the 2 x 3 matrix d(u, v)/d(X, Y, Z). (Mathics3 10 returns the transpose
   for D[{u, v}, {{X, Y, Z}}], so the Outer form is used.) *)
projectionJacobianSymbolic = Outer[D, projection[{X, Y, Z}, fx, fy, cx, cy], {X, Y, Z}];

projectionJacobian[{xv_, yv_, zv_}, fxv_, fyv_, cxv_, cyv_] :=
  projectionJacobianSymbolic /. {X -> xv, Y -> yv, Z -> zv, fx -> fxv, fy -> fyv, cx -> cxv, cy -> cyv}
