(* ::Package:: *)
(* The syllabus' functional Kalman filter (section 11.2) as functions of the case inputs.
   State {px, py, vx, vy}, measurement {px, py}. *)

(* Discrete white-noise-acceleration covariance for the state {p_1..p_dim, v_1..v_dim}. *)
whiteNoiseQ[dt_, q_, dim_Integer] := Module[{Q1d},
  Q1d = q {{0.25 dt^4, 0.5 dt^3},
           {0.5 dt^3,  dt^2}};
  (* FIX: the syllabus writes KroneckerProduct[IdentityMatrix[2], Q1d] = blkdiag(Q1d, Q1d), the
     covariance for the interleaved order {px, vx, py, vy}. For {px, py, vx, vy} the blocks of Q1d
     must multiply I2: KroneckerProduct[Q1d, IdentityMatrix[dim]]. *)
  KroneckerProduct[Q1d, IdentityMatrix[dim]]]

(* Mathics3's built-in FoldList re-evaluates the growing result list at every step, which makes it
   quadratic (40 filter steps take about a minute, 1000 would take hours). kalmanFoldList below
   computes exactly the same list {x0, f[x0, z1], f[f[x0, z1], z2], ...} in linear time with
   Fold + Sow/Reap; in Wolfram Mathematica write FoldList[kalmanStep, {x0, P0}, zs] as the
   syllabus does. *)
kalmanFoldList[f_, x0_, list_List] :=
  Prepend[Reap[Fold[Function[{acc, el}, Sow[f[acc, el]]], x0, list]][[2, 1]], x0]

(* Runs the filter over the measurement list zs (K x 2); returns {positions (K x 2), P after the
   last update (4 x 4)}. *)
kalmanCV2D[dt_, processVar_, measVar_, x0_, P0_, zs_] := Module[
  {F, FT, H, HT, I4, Q, R, kalmanStep, result},
  F = {{1, 0, dt, 0},
       {0, 1, 0, dt},
       {0, 0, 1, 0},
       {0, 0, 0, 1}} // N;
  H = {{1, 0, 0, 0},
       {0, 1, 0, 0}} // N;
  FT = Transpose[F]; HT = Transpose[H]; I4 = N[IdentityMatrix[4]];
  Q = whiteNoiseQ[dt, processVar, 2];
  R = measVar IdentityMatrix[2];
  kalmanStep[{x_, P_}, z_] := Module[{xPred, PPred, y, S, K},
    xPred = F.x;
    PPred = F.P.FT + Q;
    y = z - H.xPred;
    S = H.PPred.HT + R;
    K = PPred.HT.Inverse[S];
    {xPred + K.y, (I4 - K.H).PPred}];
  (* Mathics3 counts *every* symbol rewrite of a whole top-level evaluation against $IterationLimit
     (default 4096) instead of the length of one rewrite chain as Mathematica does, so a long
     measurement list (about 300 steps and more) ends in an $IterationLimit abort. Lifting the limit
     for the fold is harmless: the fold is a finite loop. Mathematica does not need the Block. *)
  result = Block[{$IterationLimit = Infinity}, Rest[kalmanFoldList[kalmanStep, {x0, P0}, zs]]];
  {result[[All, 1, {1, 2}]], result[[-1, 2]]}]
