/**
 * Exercise cv_model (Java): the constant-velocity model of a 2-D point, state [px, py, vx, vy].
 * Plain arrays, row-major: {@code M[i][j]} is row i. (EJML is on the class path if you prefer it.)
 */
public final class CvModel {
    private CvModel() {}

    /** F (4 x 4): moves the state by dt (positions gain dt times the velocities). */
    public static double[][] transition(double dt) {
        double[][] F = new double[4][4];
        // BEGIN SOLUTION
        for (int i = 0; i < 4; i++) F[i][i] = 1.0;
        F[0][2] = dt;
        F[1][3] = dt;
        // END SOLUTION
        return F;
    }

    /**
     * Q (4 x 4): white acceleration of variance q on each axis, constant over a step. On one axis,
     * with the state [p, v], the noise is q * Q1d, Q1d = [[dt^4/4, dt^3/2], [dt^3/2, dt^2]]: place
     * its entries for the state order [px, py, vx, vy] (which entries of Q are the (px, vx) pair?).
     */
    public static double[][] processNoise(double dt, double q) {
        double[][] Q = new double[4][4];
        // BEGIN SOLUTION
        double[][] q1 = {{Math.pow(dt, 4) / 4, Math.pow(dt, 3) / 2}, {Math.pow(dt, 3) / 2, dt * dt}};
        for (int a = 0; a < 2; a++)
            for (int b = 0; b < 2; b++)
                for (int k = 0; k < 2; k++) Q[2 * a + k][2 * b + k] = q * q1[a][b];
        // END SOLUTION
        return Q;
    }
}
