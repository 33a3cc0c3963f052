/**
 * Exercise kalman_step (Java): one Kalman filter step, predict with F, Q, then update with z.
 * Plain arrays, row-major. (EJML is on the class path if you prefer it.)
 */
public final class KalmanStep {
    private KalmanStep() {}

    /**
     * x (n) and P (n x n) hold the estimate before the step; overwrite their entries with the
     * estimate after it (x[i] = ..., P[i][j] = ...). H is m x n, R m x m, z has m entries.
     */
    public static void step(double[] x, double[][] P, double[][] F, double[][] Q, double[][] H, double[][] R,
            double[] z) {
        // BEGIN SOLUTION
        int n = x.length;
        double[] xp = mul(F, x);
        double[][] Pp = add(mul(mul(F, P), transpose(F)), Q);
        double[][] S = add(mul(mul(H, Pp), transpose(H)), R);
        double[][] K = mul(mul(Pp, transpose(H)), inverse(S));
        double[] hx = mul(H, xp);
        double[] y = new double[z.length];
        for (int i = 0; i < z.length; i++) y[i] = z[i] - hx[i];
        double[] ky = mul(K, y);
        double[][] ikh = mul(K, H);
        for (int i = 0; i < n; i++)
            for (int j = 0; j < n; j++) ikh[i][j] = (i == j ? 1.0 : 0.0) - ikh[i][j];
        double[][] Pn = add(mul(mul(ikh, Pp), transpose(ikh)), mul(mul(K, R), transpose(K)));  // Joseph form
        for (int i = 0; i < n; i++) {
            x[i] = xp[i] + ky[i];
            System.arraycopy(Pn[i], 0, P[i], 0, n);
        }
        // END SOLUTION
    }
    // BEGIN SOLUTION

    static double[][] mul(double[][] A, double[][] B) {
        double[][] C = new double[A.length][B[0].length];
        for (int i = 0; i < A.length; i++)
            for (int k = 0; k < B.length; k++)
                for (int j = 0; j < B[0].length; j++) C[i][j] += A[i][k] * B[k][j];
        return C;
    }

    static double[] mul(double[][] A, double[] v) {
        double[] r = new double[A.length];
        for (int i = 0; i < A.length; i++)
            for (int k = 0; k < v.length; k++) r[i] += A[i][k] * v[k];
        return r;
    }

    static double[][] add(double[][] A, double[][] B) {
        double[][] C = new double[A.length][A[0].length];
        for (int i = 0; i < A.length; i++)
            for (int j = 0; j < A[0].length; j++) C[i][j] = A[i][j] + B[i][j];
        return C;
    }

    static double[][] transpose(double[][] A) {
        double[][] T = new double[A[0].length][A.length];
        for (int i = 0; i < A.length; i++)
            for (int j = 0; j < A[0].length; j++) T[j][i] = A[i][j];
        return T;
    }

    /** Gauss-Jordan inverse with partial pivoting (S is small and positive definite). */
    static double[][] inverse(double[][] A) {
        int n = A.length;
        double[][] M = new double[n][2 * n];
        for (int i = 0; i < n; i++) {
            System.arraycopy(A[i], 0, M[i], 0, n);
            M[i][n + i] = 1.0;
        }
        for (int c = 0; c < n; c++) {
            int p = c;
            for (int r = c + 1; r < n; r++) if (Math.abs(M[r][c]) > Math.abs(M[p][c])) p = r;
            double[] t = M[c]; M[c] = M[p]; M[p] = t;
            double d = M[c][c];
            for (int j = 0; j < 2 * n; j++) M[c][j] /= d;
            for (int r = 0; r < n; r++) {
                if (r == c) continue;
                double f = M[r][c];
                for (int j = 0; j < 2 * n; j++) M[r][j] -= f * M[c][j];
            }
        }
        double[][] inv = new double[n][n];
        for (int i = 0; i < n; i++) System.arraycopy(M[i], n, inv[i], 0, n);
        return inv;
    }
    // END SOLUTION
}
