package flowtrack.ports;

import static flowtrack.ports.MatrixOps.copyMatrix;
import static flowtrack.ports.MatrixOps.identityMatrix;
import static flowtrack.ports.MatrixOps.matAdd;
import static flowtrack.ports.MatrixOps.matInv2x2;
import static flowtrack.ports.MatrixOps.matMul;
import static flowtrack.ports.MatrixOps.matSub;
import static flowtrack.ports.MatrixOps.transpose;

/**
 * The syllabus' constant-velocity Kalman filter (section 10) with plain {@code double[][]} arrays,
 * the helpers it leaves out implemented in {@link MatrixOps}, and its process noise fixed.
 *
 * <p>State {@code [px, py, vx, vy]}, measurement {@code [px, py]}.
 */
public class KalmanFilterCV2D {
    private final double dt;
    private final double[][] F = new double[4][4];
    private final double[][] H = new double[2][4];
    private final double[][] Q;
    private final double[][] R = new double[2][2];
    private final double[] x = new double[4];
    private final double[][] P = new double[4][4];

    /** The syllabus' constructor: {@code x0 = 0}, {@code P0 = 1e3 I}. */
    public KalmanFilterCV2D(double dt, double processVar, double measVar) {
        this(dt, processVar, measVar, new double[4], identityMatrix(4, 1e3));
    }

    /** With an explicit initial state {@code x0 (4)} and covariance {@code P0 (4x4)}. */
    public KalmanFilterCV2D(double dt, double processVar, double measVar, double[] x0, double[][] P0) {
        if (!(measVar > 0)) {
            throw new IllegalArgumentException("measVar: expected > 0, got " + measVar);
        }
        if (x0 == null || x0.length != 4) {
            throw new IllegalArgumentException("x0: expected length 4");
        }
        if (P0 == null || P0.length != 4 || P0[0].length != 4) {
            throw new IllegalArgumentException("P0: expected a 4x4 matrix");
        }
        this.dt = dt;

        // Initialize F as identity with dt in velocity terms
        identityMatrix(F, 1.0);
        F[0][2] = dt;
        F[1][3] = dt;

        // Measurement matrix
        H[0][0] = 1.0;
        H[1][1] = 1.0;

        // FIX (syllabus bug): the syllabus adds q*Q1d at blocks (0,0) and (2,2), i.e. blkdiag(Q1d, Q1d),
        // which for the state order [px, py, vx, vy] correlates px with py. The white-noise-
        // acceleration model needs Q1d ⊗ I2: px-vx and py-vy are the correlated pairs.
        this.Q = WhiteNoiseQ.q(dt, processVar, 2);

        R[0][0] = measVar;
        R[1][1] = measVar;

        System.arraycopy(x0, 0, x, 0, 4);
        copyMatrix(P0, P);
    }

    public void predict() {
        double[] xNew = matMul(F, x);
        double[][] PNew = matAdd(matMul(F, matMul(P, transpose(F))), Q);
        System.arraycopy(xNew, 0, x, 0, 4);
        copyMatrix(PNew, P);
    }

    public void update(double[] z) {
        if (z == null || z.length != 2) {
            throw new IllegalArgumentException("z: expected a measurement of length 2");
        }
        double[] zPred = matMul(H, x);
        double[] y = matSub(z, zPred);
        double[][] S = matAdd(matMul(H, matMul(P, transpose(H))), R);
        double[][] SInv = matInv2x2(S);
        double[][] K = matMul(matMul(P, transpose(H)), SInv);

        double[] Ky = matMul(K, y);
        for (int i = 0; i < 4; ++i) {
            x[i] += Ky[i];
        }

        double[][] I = identityMatrix(4, 1.0);
        double[][] KH = matMul(K, H);
        double[][] PNew = matMul(matSub(I, KH), P);
        copyMatrix(PNew, P);
    }

    public double[] position() {
        return new double[] {x[0], x[1]};
    }

    /** A copy of the covariance P (4x4). */
    public double[][] covariance() {
        double[][] c = new double[4][4];
        copyMatrix(P, c);
        return c;
    }

    public double dt() {
        return dt;
    }
}
