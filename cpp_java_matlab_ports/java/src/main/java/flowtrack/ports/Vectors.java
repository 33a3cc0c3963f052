package flowtrack.ports;

import com.google.gson.JsonArray;
import com.google.gson.JsonElement;
import com.google.gson.JsonObject;
import com.google.gson.JsonParser;
import java.io.IOException;
import java.io.Reader;
import java.nio.charset.StandardCharsets;
import java.nio.file.Files;
import java.nio.file.Path;

/** Reading the shared test vectors (gson) and comparing with a case's tolerance. */
public final class Vectors {
    private Vectors() {
    }

    /** The parsed {@code <dir>/<problem>.json}, or {@code null} when the file does not exist. */
    public static JsonObject load(Path dir, String problem) throws IOException {
        Path file = dir.resolve(problem + ".json");
        if (!Files.exists(file)) {
            return null;
        }
        try (Reader r = Files.newBufferedReader(file, StandardCharsets.UTF_8)) {
            return JsonParser.parseReader(r).getAsJsonObject();
        }
    }

    public static double[] vec(JsonElement e) {
        JsonArray a = e.getAsJsonArray();
        double[] v = new double[a.size()];
        for (int i = 0; i < v.length; ++i) {
            v[i] = a.get(i).getAsDouble();
        }
        return v;
    }

    public static double[][] mat(JsonElement e) {
        JsonArray a = e.getAsJsonArray();
        double[][] m = new double[a.size()][];
        for (int i = 0; i < m.length; ++i) {
            m[i] = vec(a.get(i));
        }
        return m;
    }

    /**
     * Accumulates an elementwise comparison: the case passes iff every {@code |got - exp| <= atol
     * + rtol |exp|}; {@code maxErr} is the largest {@code |got - exp|}.
     */
    public static final class Check {
        public final double rtol;
        public final double atol;
        public double maxErr = 0.0;
        public boolean ok = true;
        public String message = "";

        public Check(double rtol, double atol) {
            this.rtol = rtol;
            this.atol = atol;
        }

        public Check(JsonObject c) {
            this(c.get("rtol").getAsDouble(), c.get("atol").getAsDouble());
        }

        public void add(String what, double got, double exp) {
            double err = Math.abs(got - exp);
            if (Double.isNaN(err)) {
                err = Double.POSITIVE_INFINITY;
            }
            maxErr = Math.max(maxErr, err);
            if (!(err <= atol + rtol * Math.abs(exp)) && ok) {
                ok = false;
                message = what + ": got " + got + ", expected " + exp;
            }
        }

        public void add(String what, double[] got, double[] exp) {
            if (got.length != exp.length) {
                fail(what + ": length " + got.length + ", expected " + exp.length);
                return;
            }
            for (int i = 0; i < got.length; ++i) {
                add(what + "[" + i + "]", got[i], exp[i]);
            }
        }

        public void add(String what, double[][] got, double[][] exp) {
            if (got.length != exp.length) {
                fail(what + ": " + got.length + " rows, expected " + exp.length);
                return;
            }
            for (int i = 0; i < got.length; ++i) {
                add(what + "[" + i + "]", got[i], exp[i]);
            }
        }

        public void fail(String why) {
            ok = false;
            maxErr = Double.NaN;
            message = why;
        }

        /** The harness line {@code CASE problem id PASS|FAIL err message}. */
        public String line(String problem, String id) {
            return "CASE " + problem + " " + id + " " + (ok ? "PASS" : "FAIL") + " " + maxErr + " "
                    + (ok ? "ok" : message.replaceAll("\\s+", " "));
        }
    }
}
