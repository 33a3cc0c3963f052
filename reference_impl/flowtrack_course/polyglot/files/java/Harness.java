// flowtrack exercise harness (Java): reads a vectors file, calls your methods, prints the outputs.
//
//   java Harness PROBLEM CASES.json           prints  OUTPUT <case id> <json of the outputs>  per case
//   java Harness --check PROBLEM PUBLIC.json  also compares with each case's "expected" and prints
//                                             CASE <problem> <id> PASS|FAIL <err> <message>
// The file is in the course's shared vectors format. Do not edit (the grader uses its own copy).
import com.google.gson.JsonArray;
import com.google.gson.JsonElement;
import com.google.gson.JsonObject;
import com.google.gson.JsonParser;
import java.nio.charset.StandardCharsets;
import java.nio.file.Files;
import java.nio.file.Paths;
import java.util.LinkedHashMap;
import java.util.Map;

public final class Harness {
    private Harness() {}

    static double[] vec(JsonElement e) {
        JsonArray a = e.getAsJsonArray();
        double[] v = new double[a.size()];
        for (int i = 0; i < v.length; i++) v[i] = a.get(i).getAsDouble();
        return v;
    }

    static double[][] mat(JsonElement e) {
        JsonArray a = e.getAsJsonArray();
        double[][] m = new double[a.size()][];
        for (int i = 0; i < m.length; i++) m[i] = vec(a.get(i));
        return m;
    }

    static String json(double[] v) {
        StringBuilder b = new StringBuilder("[");
        for (int i = 0; i < v.length; i++) b.append(i > 0 ? ", " : "").append(num(v[i]));
        return b.append("]").toString();
    }

    static String json(double[][] m) {
        StringBuilder b = new StringBuilder("[");
        for (int i = 0; i < m.length; i++) b.append(i > 0 ? ", " : "").append(m[i] == null ? "null" : json(m[i]));
        return b.append("]").toString();
    }

    static String num(double x) {
        return Double.isFinite(x) ? Double.toString(x) : "null";
    }

    static double[] toDouble(int[] v) {
        double[] d = new double[v.length];
        for (int i = 0; i < v.length; i++) d[i] = v[i];
        return d;
    }

    static Map<String, String> solve(String problem, JsonObject in) {
        Map<String, String> out = new LinkedHashMap<>();
        switch (problem) {
            case "cv_model": {
                double dt = in.get("dt").getAsDouble(), q = in.get("q").getAsDouble();
                out.put("F", json(CvModel.transition(dt)));
                out.put("Q", json(CvModel.processNoise(dt, q)));
                break;
            }
            case "kalman_step": {
                double[] x = vec(in.get("x"));
                double[][] P = mat(in.get("P"));
                KalmanStep.step(x, P, mat(in.get("F")), mat(in.get("Q")), mat(in.get("H")), mat(in.get("R")),
                        vec(in.get("z")));
                out.put("x", json(x));
                out.put("P", json(P));
                break;
            }
            case "projection_jacobian": {
                out.put("J", json(ProjectionJacobian.jacobian(vec(in.get("X")), in.get("fx").getAsDouble(),
                        in.get("fy").getAsDouble(), in.get("cx").getAsDouble(), in.get("cy").getAsDouble())));
                break;
            }
            case "mahalanobis_gating": {
                double[] d2 = MahalanobisGating.d2(vec(in.get("z_pred")), mat(in.get("S")), mat(in.get("Z")));
                out.put("d2", json(d2));
                out.put("inside", json(toDouble(MahalanobisGating.gate(d2, in.get("gate").getAsDouble()))));
                break;
            }
            case "assignment": {
                double[][] C = mat(in.get("C"));
                if (C.length > 0 && C.length > C[0].length)
                    throw new IllegalArgumentException("C must have at least as many columns as rows");
                out.put("assignment", json(toDouble(Assignment.solve(C))));
                break;
            }
            default:
                throw new IllegalArgumentException("unknown problem " + problem);
        }
        return out;
    }

    static double compare(JsonElement got, JsonElement exp, double rtol, double atol, StringBuilder msg) {
        if (exp.isJsonArray()) {
            JsonArray g = got.isJsonArray() ? got.getAsJsonArray() : null, e = exp.getAsJsonArray();
            if (g == null || g.size() != e.size()) {
                if (msg.length() == 0) msg.append("wrong shape");
                return Double.POSITIVE_INFINITY;
            }
            double worst = 0;
            for (int i = 0; i < e.size(); i++) worst = Math.max(worst, compare(g.get(i), e.get(i), rtol, atol, msg));
            return worst;
        }
        if (got.isJsonNull()) {
            if (msg.length() == 0) msg.append("not a number");
            return Double.POSITIVE_INFINITY;
        }
        double g = got.getAsDouble(), e = exp.getAsDouble(), err = Math.abs(g - e);
        if (!(err <= atol + rtol * Math.abs(e)) && msg.length() == 0) msg.append("got ").append(g).append(", expected ").append(e);
        return err;
    }

    public static void main(String[] args) throws Exception {
        boolean check = args.length == 3 && args[0].equals("--check");
        if (args.length != 2 && !check) {
            System.err.println("usage: java Harness [--check] PROBLEM CASES.json");
            System.exit(2);
        }
        String problem = args[args.length - 2];
        JsonObject doc = JsonParser.parseString(
                new String(Files.readAllBytes(Paths.get(args[args.length - 1])), StandardCharsets.UTF_8)).getAsJsonObject();
        boolean allOk = true;
        for (JsonElement ce : doc.getAsJsonArray("cases")) {
            JsonObject c = ce.getAsJsonObject();
            String id = c.get("id").getAsString();
            Map<String, String> out;
            try {
                out = solve(problem, c.getAsJsonObject("input"));
            } catch (RuntimeException e) {
                System.out.println("ERROR " + id + " " + String.valueOf(e).replace('\n', ' '));
                allOk = false;
                continue;
            }
            StringBuilder b = new StringBuilder("{");
            for (Map.Entry<String, String> kv : out.entrySet())
                b.append(b.length() > 1 ? ", " : "").append('"').append(kv.getKey()).append("\": ").append(kv.getValue());
            String text = b.append("}").toString();
            System.out.println("OUTPUT " + id + " " + text);
            if (check) {
                JsonObject got = JsonParser.parseString(text).getAsJsonObject();
                StringBuilder msg = new StringBuilder();
                double worst = 0;
                for (Map.Entry<String, JsonElement> kv : c.getAsJsonObject("expected").entrySet()) {
                    StringBuilder m = new StringBuilder();
                    worst = Math.max(worst, got.has(kv.getKey())
                            ? compare(got.get(kv.getKey()), kv.getValue(), c.get("rtol").getAsDouble(), c.get("atol").getAsDouble(), m)
                            : Double.POSITIVE_INFINITY);
                    if (!got.has(kv.getKey())) m.append("missing");
                    if (m.length() > 0 && msg.length() == 0) msg.append(kv.getKey()).append(": ").append(m);
                }
                boolean ok = msg.length() == 0;
                allOk &= ok;
                System.out.println("CASE " + problem + " " + id + (ok ? " PASS " : " FAIL ") + worst + " " + (ok ? "ok" : msg));
            }
        }
        System.exit(check && !allOk ? 1 : 0);
    }
}
