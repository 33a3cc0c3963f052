package flowtrack.ports;

import static org.junit.jupiter.api.Assertions.assertEquals;
import static org.junit.jupiter.api.Assertions.assertNotNull;
import static org.junit.jupiter.api.Assertions.assertThrows;
import static org.junit.jupiter.api.Assertions.assertTrue;

import com.google.gson.JsonElement;
import com.google.gson.JsonObject;
import java.nio.file.Path;
import java.util.ArrayList;
import java.util.List;
import java.util.Random;
import org.junit.jupiter.api.DynamicTest;
import org.junit.jupiter.api.Test;
import org.junit.jupiter.api.TestFactory;

/**
 * JUnit 5 tests of the Java ports: every vector case of every problem per language (directory from
 * the system property {@code flowtrack.vectors}), plus checks against independent oracles (finite
 * differences, the definition of the inverse, the structure of Q).
 */
class PortsTest {
    private static Path vectorsDir() {
        String d = System.getProperty("flowtrack.vectors");
        assertNotNull(d, "set -Dflowtrack.vectors=<dir with the vector JSON files>");
        return Path.of(d);
    }

    @TestFactory
    List<DynamicTest> vectorCases() throws Exception {
        List<DynamicTest> tests = new ArrayList<>();
        for (var entry : Problems.BY_LANGUAGE.entrySet()) {
            String language = entry.getKey();
            for (String problem : entry.getValue()) {
                JsonObject file = Vectors.load(vectorsDir(), problem);
                assertNotNull(file, "vector file " + problem + ".json is missing");
                for (JsonElement e : Problems.cases(file)) {
                    JsonObject c = e.getAsJsonObject();
                    String name = language + " " + problem + " " + c.get("id").getAsString();
                    tests.add(DynamicTest.dynamicTest(name, () -> {
                        Vectors.Check chk = Problems.run(language, problem, c);
                        assertTrue(chk.ok, name + ": " + chk.message + " (max error " + chk.maxErr + ")");
                    }));
                }
            }
        }
        assertTrue(tests.size() > 0, "no vector cases found");
        return tests;
    }

    @Test
    void processNoiseIsKroneckerNotBlockDiagonal() {
        double dt = 0.2;
        double q = 3.0;
        double[][] Q = WhiteNoiseQ.q(dt, q, 2);
        // state [px, py, vx, vy]: px-vx correlated (q dt^3/2), px-py not (blkdiag would give the reverse)
        assertEquals(q * Math.pow(dt, 3) / 2, Q[0][2], 1e-15);
        assertEquals(q * Math.pow(dt, 3) / 2, Q[1][3], 1e-15);
        assertEquals(0.0, Q[0][1]);
        assertEquals(0.0, Q[2][3]);
        assertEquals(q * Math.pow(dt, 4) / 4, Q[1][1], 1e-15);
        assertEquals(q * dt * dt, Q[3][3], 1e-15);
    }

    @Test
    void inverse2x2TimesMatrixIsIdentity() {
        double[][] s = {{4.0, 1.5}, {-0.5, 2.0}};
        double[][] p = MatrixOps.matMul(s, MatrixOps.matInv2x2(s));
        assertEquals(1.0, p[0][0], 1e-15);
        assertEquals(0.0, p[0][1], 1e-15);
        assertEquals(0.0, p[1][0], 1e-15);
        assertEquals(1.0, p[1][1], 1e-15);
        assertThrows(IllegalArgumentException.class, () -> MatrixOps.matInv2x2(new double[][] {{1, 2}, {2, 4}}));
    }

    @Test
    void jacobianMatchesCentralDifferences() {
        double fx = 520.0;
        double fy = 515.0;
        double cx = 319.5;
        double cy = 239.5;
        double[] p = {0.3, -0.2, 1.7};
        double[][] J = ProjectionJacobian.jacobian(p, fx, fy, cx, cy);
        double h = 1e-6;
        for (int j = 0; j < 3; ++j) {
            double[] a = p.clone();
            double[] b = p.clone();
            a[j] += h;
            b[j] -= h;
            double du = (fx * a[0] / a[2] - fx * b[0] / b[2]) / (2 * h);
            double dv = (fy * a[1] / a[2] - fy * b[1] / b[2]) / (2 * h);
            assertEquals(du, J[0][j], 1e-5);
            assertEquals(dv, J[1][j], 1e-5);
        }
        assertThrows(IllegalArgumentException.class, () -> ProjectionJacobian.jacobian(new double[] {0, 0, -1}, fx, fy, cx, cy));
    }

    @Test
    void plainAndEjmlFiltersAgree() {
        KalmanFilterCV2D a = new KalmanFilterCV2D(0.1, 1.0, 4.0);
        KalmanFilterCV2DEjml b = new KalmanFilterCV2DEjml(0.1, 1.0, 4.0);
        Random rng = new Random(1);
        for (int k = 0; k < 100; ++k) {
            double[] z = {0.5 * k + rng.nextGaussian(), 2.0 - 0.1 * k + rng.nextGaussian()};
            a.predict();
            a.update(z);
            b.predict();
            b.update(z);
        }
        assertEquals(a.position()[0], b.position()[0], 1e-9);
        assertEquals(a.position()[1], b.position()[1], 1e-9);
        double[][] pa = a.covariance();
        double[][] pb = b.covariance();
        for (int i = 0; i < 4; ++i) {
            for (int j = 0; j < 4; ++j) {
                assertEquals(pa[i][j], pb[i][j], 1e-9);
            }
        }
    }

    @Test
    void badMeasurementIsRejected() {
        KalmanFilterCV2D a = new KalmanFilterCV2D(0.1, 1.0, 4.0);
        assertThrows(IllegalArgumentException.class, () -> a.update(new double[] {1.0}));
    }
}
