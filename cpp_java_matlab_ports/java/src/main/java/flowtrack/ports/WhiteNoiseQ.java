package flowtrack.ports;

/**
 * Discrete white-noise-acceleration process covariance for the state {@code [p_1..p_d, v_1..v_d]}.
 *
 * <p>{@code Q = Q1d ⊗ I_d} with {@code Q1d = q [[dt^4/4, dt^3/2], [dt^3/2, dt^2]]}: the position and
 * velocity of the same axis are correlated, different axes are not. The syllabus builds
 * {@code blkdiag(Q1d, Q1d)} instead, which for this state order correlates {@code p_x} with
 * {@code p_y} and {@code v_x} with {@code v_y}: wrong.
 */
public final class WhiteNoiseQ {
    private WhiteNoiseQ() {
    }

    /** The 2x2 one-axis block {@code q [[dt^4/4, dt^3/2], [dt^3/2, dt^2]]}. */
    public static double[][] q1d(double dt, double q) {
        if (!(dt > 0) || !Double.isFinite(dt)) {
            throw new IllegalArgumentException("dt: expected a finite dt > 0, got " + dt);
        }
        if (!(q >= 0) || !Double.isFinite(q)) {
            throw new IllegalArgumentException("q: expected a finite q >= 0, got " + q);
        }
        double dt2 = dt * dt;
        double dt3 = dt2 * dt;
        double dt4 = dt2 * dt2;
        return new double[][] {{q * 0.25 * dt4, q * 0.5 * dt3}, {q * 0.5 * dt3, q * dt2}};
    }

    /** {@code Q1d ⊗ I_dim}, shape (2 dim x 2 dim). */
    public static double[][] q(double dt, double q, int dim) {
        if (dim < 1) {
            throw new IllegalArgumentException("dim: expected dim >= 1, got " + dim);
        }
        return MatrixOps.kron(q1d(dt, q), MatrixOps.identityMatrix(dim, 1.0));
    }
}
