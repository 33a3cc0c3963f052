/**
 * Exercise projection_jacobian (Java): d(u, v)/d(X, Y, Z) (2 x 3) of the pinhole projection
 * u = fx X/Z + cx, v = fy Y/Z + cy at the point X (3 entries). Plain arrays, row-major.
 */
public final class ProjectionJacobian {
    private ProjectionJacobian() {}

    public static double[][] jacobian(double[] X, double fx, double fy, double cx, double cy) {
        double[][] J = new double[2][3];
        // BEGIN SOLUTION
        double iz = 1.0 / X[2];
        J[0][0] = fx * iz;
        J[0][2] = -fx * X[0] * iz * iz;
        J[1][1] = fy * iz;
        J[1][2] = -fy * X[1] * iz * iz;
        // END SOLUTION
        return J;
    }
}
