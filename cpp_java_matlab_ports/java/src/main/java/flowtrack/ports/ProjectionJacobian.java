package flowtrack.ports;

/**
 * Jacobian of the pinhole projection {@code u = fx X/Z + cx, v = fy Y/Z + cy} with respect to the
 * camera-frame point {@code (X, Y, Z)}:
 * {@code J = [[fx/Z, 0, -fx X/Z^2], [0, fy/Z, -fy Y/Z^2]]}.
 */
public final class ProjectionJacobian {
    private ProjectionJacobian() {
    }

    /** The 2x3 Jacobian at {@code p = (X, Y, Z)}, Z > 0. */
    public static double[][] jacobian(double[] p, double fx, double fy, double cx, double cy) {
        if (p == null || p.length != 3) {
            throw new IllegalArgumentException("X: expected a point of length 3");
        }
        double z = p[2];
        if (!(z > 0) || !Double.isFinite(z)) {
            throw new IllegalArgumentException("X: expected depth Z > 0, got " + z);
        }
        return new double[][] {
            {fx / z, 0.0, -fx * p[0] / (z * z)},
            {0.0, fy / z, -fy * p[1] / (z * z)},
        };
    }
}
