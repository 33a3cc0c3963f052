package flowtrack.ports;

import org.ejml.simple.SimpleMatrix;

/**
 * The same constant-velocity filter on EJML's {@link SimpleMatrix}; the process noise is built as
 * {@code Q1d.kron(I2)} (the syllabus' {@code blkdiag(Q1d, Q1d)} is wrong for the state order
 * {@code [px, py, vx, vy]}).
 */
public class KalmanFilterCV2DEjml {
    private final SimpleMatrix F;
    private final SimpleMatrix H;
    private final SimpleMatrix Q;
    private final SimpleMatrix R;
    private final SimpleMatrix I4 = SimpleMatrix.identity(4);
    private SimpleMatrix x;
    private SimpleMatrix P;

    public KalmanFilterCV2DEjml(double dt, double processVar, double measVar) {
        this(dt, processVar, measVar, new double[4], MatrixOps.identityMatrix(4, 1e3));
    }

    public KalmanFilterCV2DEjml(double dt, double processVar, double measVar, double[] x0, double[][] P0) {
        if (!(dt > 0)) {
            throw new IllegalArgumentException("dt: expected > 0, got " + dt);
        }
        if (!(measVar > 0)) {
            throw new IllegalArgumentException("measVar: expected > 0, got " + measVar);
        }
        if (x0 == null || x0.length != 4 || P0 == null || P0.length != 4 || P0[0].length != 4) {
            throw new IllegalArgumentException("x0, P0: expected shapes (4) and (4x4)");
        }
        F = SimpleMatrix.identity(4);
        F.set(0, 2, dt);
        F.set(1, 3, dt);
        H = new SimpleMatrix(new double[][] {{1, 0, 0, 0}, {0, 1, 0, 0}});
        double dt2 = dt * dt;
        SimpleMatrix q1d = new SimpleMatrix(new double[][] {
            {0.25 * dt2 * dt2, 0.5 * dt2 * dt},
            {0.5 * dt2 * dt, dt2},
        }).scale(processVar);
        // FIX (syllabus bug): Q = Q1d ⊗ I2, not blkdiag(Q1d, Q1d).
        Q = q1d.kron(SimpleMatrix.identity(2));
        R = SimpleMatrix.identity(2).scale(measVar);
        x = new SimpleMatrix(4, 1, true, x0);
        P = new SimpleMatrix(P0);
    }

    /** {@code Q1d ⊗ I_dim} via EJML's Kronecker product. */
    public static SimpleMatrix whiteNoiseQ(double dt, double q, int dim) {
        return new SimpleMatrix(WhiteNoiseQ.q1d(dt, q)).kron(SimpleMatrix.identity(dim));
    }

    public void predict() {
        x = F.mult(x);
        P = F.mult(P).mult(F.transpose()).plus(Q);
    }

    public void update(double[] z) {
        if (z == null || z.length != 2) {
            throw new IllegalArgumentException("z: expected a measurement of length 2");
        }
        SimpleMatrix y = new SimpleMatrix(2, 1, true, z).minus(H.mult(x));
        SimpleMatrix S = H.mult(P).mult(H.transpose()).plus(R);
        SimpleMatrix K = P.mult(H.transpose()).mult(S.invert());
        x = x.plus(K.mult(y));
        P = I4.minus(K.mult(H)).mult(P);
    }

    public double[] position() {
        return new double[] {x.get(0), x.get(1)};
    }

    public double[][] covariance() {
        return toArray(P);
    }

    /** The entries of {@code m} as a new row-major {@code double[rows][cols]}. */
    public static double[][] toArray(SimpleMatrix m) {
        double[][] a = new double[m.numRows()][m.numCols()];
        for (int i = 0; i < a.length; ++i) {
            for (int j = 0; j < a[0].length; ++j) {
                a[i][j] = m.get(i, j);
            }
        }
        return a;
    }
}
