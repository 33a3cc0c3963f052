function J = projection_jacobian(X, fx, fy, cx, cy)
% PROJECTION_JACOBIAN  2 x 3 Jacobian of the pinhole projection u = fx X/Z + cx, v = fy Y/Z + cy.
%
%   J = projection_jacobian(X, fx, fy, cx, cy), X = [X Y Z] with Z > 0:
%   J = [fx/Z 0 -fx X/Z^2; 0 fy/Z -fy Y/Z^2]   (cx, cy do not enter).
  if numel(X) ~= 3, error('projection_jacobian: X: expected 3 values [X Y Z]'); end
  if ~(X(3) > 0), error('projection_jacobian: X: expected depth Z > 0'); end
  Z = X(3);
  J = [fx / Z, 0, -fx * X(1) / Z^2;
       0, fy / Z, -fy * X(2) / Z^2];
end
