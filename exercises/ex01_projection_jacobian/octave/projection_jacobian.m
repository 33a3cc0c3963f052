function J = projection_jacobian(X, fx, fy, cx, cy)
  % PROJECTION_JACOBIAN  d(u, v)/d(X, Y, Z) (2x3) of u = fx X/Z + cx, v = fy Y/Z + cy at the point X (3x1).
  J = zeros(2, 3);
  % BEGIN SOLUTION
  iz = 1 / X(3);
  J = [fx * iz, 0, -fx * X(1) * iz^2; 0, fy * iz, -fy * X(2) * iz^2];
  % END SOLUTION
end
