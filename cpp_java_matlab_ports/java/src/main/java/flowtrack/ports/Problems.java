package flowtrack.ports;

import com.google.gson.JsonArray;
import com.google.gson.JsonObject;
import java.util.List;
import java.util.Map;

/** Which problems each Java port implements, and how one vector case is run and checked. */
public final class Problems {
    private Problems() {
    }

    /** Problems per language (the harness' first argument). */
    public static final Map<String, List<String>> BY_LANGUAGE = Map.of(
            "java", List.of("kalman_cv2d", "white_noise_q", "projection_jacobian"),
            "java-ejml", List.of("kalman_cv2d", "white_noise_q"),
            "java-opencv", List.of("lucas_kanade"));

    /** Runs one case of {@code problem} with the {@code language} port; never throws. */
    public static Vectors.Check run(String language, String problem, JsonObject c) {
        Vectors.Check chk = new Vectors.Check(c);
        try {
            JsonObject in = c.getAsJsonObject("input");
            JsonObject exp = c.getAsJsonObject("expected");
            switch (problem) {
                case "kalman_cv2d" -> kalman(language.equals("java-ejml"), in, exp, chk);
                case "white_noise_q" -> {
                    double dt = in.get("dt").getAsDouble();
                    double q = in.get("q").getAsDouble();
                    int dim = in.get("dim").getAsInt();
                    double[][] got = language.equals("java-ejml")
                            ? KalmanFilterCV2DEjml.toArray(KalmanFilterCV2DEjml.whiteNoiseQ(dt, q, dim))
                            : WhiteNoiseQ.q(dt, q, dim);
                    chk.add("Q", got, Vectors.mat(exp.get("Q")));
                }
                case "projection_jacobian" -> {
                    double[][] got = ProjectionJacobian.jacobian(Vectors.vec(in.get("X")),
                            in.get("fx").getAsDouble(), in.get("fy").getAsDouble(),
                            in.get("cx").getAsDouble(), in.get("cy").getAsDouble());
                    chk.add("J", got, Vectors.mat(exp.get("J")));
                }
                case "lucas_kanade" -> LucasKanade.check(in, exp, chk);
                default -> chk.fail("problem " + problem + " is not implemented by " + language);
            }
        } catch (RuntimeException | LinkageError e) {
            chk.fail(e.getClass().getSimpleName() + ": " + e.getMessage());
        }
        return chk;
    }

    private static void kalman(boolean ejml, JsonObject in, JsonObject exp, Vectors.Check chk) {
        double dt = in.get("dt").getAsDouble();
        double q = in.get("process_var").getAsDouble();
        double r = in.get("meas_var").getAsDouble();
        double[] x0 = in.has("x0") ? Vectors.vec(in.get("x0")) : new double[4];
        double[][] p0 = in.has("P0") ? Vectors.mat(in.get("P0")) : MatrixOps.identityMatrix(4, 1e3);
        double[][] zs = Vectors.mat(in.get("measurements"));
        double[][] pos = new double[zs.length][];
        double[][] pFinal;
        if (ejml) {
            KalmanFilterCV2DEjml kf = new KalmanFilterCV2DEjml(dt, q, r, x0, p0);
            for (int k = 0; k < zs.length; ++k) {
                kf.predict();
                kf.update(zs[k]);
                pos[k] = kf.position();
            }
            pFinal = kf.covariance();
        } else {
            KalmanFilterCV2D kf = new KalmanFilterCV2D(dt, q, r, x0, p0);
            for (int k = 0; k < zs.length; ++k) {
                kf.predict();
                kf.update(zs[k]);
                pos[k] = kf.position();
            }
            pFinal = kf.covariance();
        }
        chk.add("positions", pos, Vectors.mat(exp.get("positions")));
        chk.add("P_final", pFinal, Vectors.mat(exp.get("P_final")));
    }

    /** The cases array of a loaded vector file. */
    public static JsonArray cases(JsonObject file) {
        return file.getAsJsonArray("cases");
    }
}
