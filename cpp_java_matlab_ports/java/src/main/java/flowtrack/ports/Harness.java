package flowtrack.ports;

import com.google.gson.JsonElement;
import com.google.gson.JsonObject;
import java.nio.file.Path;
import java.util.List;

/**
 * {@code java flowtrack.ports.Harness <language> <vectors_dir>}: runs every case of every problem
 * the language implements and prints {@code CASE problem id PASS|FAIL max_abs_err message} lines.
 * Exit status 1 when any case fails.
 */
public final class Harness {
    private Harness() {
    }

    public static void main(String[] args) throws Exception {
        if (args.length != 2 || !Problems.BY_LANGUAGE.containsKey(args[0])) {
            System.err.println("usage: Harness " + Problems.BY_LANGUAGE.keySet() + " VECTORS_DIR");
            System.exit(2);
        }
        String language = args[0];
        Path dir = Path.of(args[1]);
        boolean allOk = true;
        List<String> problems = Problems.BY_LANGUAGE.get(language);
        for (String problem : problems) {
            JsonObject file = Vectors.load(dir, problem);
            if (file == null) {
                System.out.println("CASE " + problem + " - FAIL nan vector file " + problem + ".json missing");
                allOk = false;
                continue;
            }
            for (JsonElement e : Problems.cases(file)) {
                JsonObject c = e.getAsJsonObject();
                Vectors.Check chk = Problems.run(language, problem, c);
                System.out.println(chk.line(problem, c.get("id").getAsString()));
                allOk &= chk.ok;
            }
        }
        System.out.flush();
        System.exit(allOk ? 0 : 1);
    }
}
