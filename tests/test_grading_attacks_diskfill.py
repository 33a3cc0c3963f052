"""A student who fills the disk must not hurt the other students, in that run or the next.

The red team filled a filesystem shared with the grader's output: every honest student of the next
run scored 0 ("No space left on device") and grades.csv could not be written. Here a small ext4
image is loop-mounted (as root) and everything the grader writes goes on it: the output folders
(results, feedback, grades.csv, gradebook.db), the sandbox cache with the students' work area
(``FLOWTRACK_SANDBOX_CACHE``) and the grader's own temporary folder (``TMPDIR``). A ballast file
leaves 96 MiB free, less than one student's disk limit (256 MiB), so the attacker really fills it.
The class is graded with ``--jobs 2`` (the attacker next to honest students), then an honest class
in a second run on the same filesystem.

Under bubblewrap the students write only to their sandbox's tmpfs (RAM, bounded), so the image
never fills. In the setpriv mode (and the fallback) a student writes to the work area on the host's
filesystem: there the grader refuses to start unless it keeps a reserve no student can take (the
filesystem's root reservation, the sandbox running as an unprivileged uid), and with one it grades
everyone in full. Skipped unless root with loop devices and ``mkfs.ext4``.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from grading_helpers import get_exercise, source_notebook, use_sandbox_mode

pytestmark = pytest.mark.xdist_group("sandbox")

MiB = 1 << 20
EXERCISE = "ex05_cv_model"
TOOLS = ("mkfs.ext4", "losetup", "mount", "umount", "tune2fs")


def _loop_ok() -> str:
    if os.geteuid() != 0:
        return "loop-mounting a filesystem needs root"
    if not Path("/dev/loop-control").exists():
        return "no loop devices (/dev/loop-control)"
    missing = [t for t in TOOLS if shutil.which(t) is None]
    return f"missing {', '.join(missing)}" if missing else ""


needs_loop = pytest.mark.skipif(bool(_loop_ok()), reason=_loop_ok() or "ok")


@pytest.fixture
def small_fs(tmp_path):
    """A 384 MiB ext4 image without a root reservation (``-m 0``, the worst case), loop-mounted on a
    folder the sandbox's uid can traverse; unmounted and detached afterwards."""
    img = tmp_path / "disk.img"
    with open(img, "wb") as f:
        f.truncate(384 * MiB)
    subprocess.run(["mkfs.ext4", "-q", "-F", "-m", "0", "-b", "4096", str(img)], check=True)
    dev = subprocess.run(["losetup", "--find", "--show", str(img)], check=True, capture_output=True,
                         text=True).stdout.strip()
    mnt = Path(tempfile.mkdtemp(prefix="flowtrack-diskfill-", dir="/tmp"))
    mounted = False
    try:
        subprocess.run(["mount", dev, str(mnt)], check=True)
        mounted = True
        os.chmod(mnt, 0o755)
        yield mnt, dev
    finally:
        if mounted:
            if subprocess.run(["umount", str(mnt)]).returncode != 0:
                subprocess.run(["umount", "-l", str(mnt)])
        subprocess.run(["losetup", "-d", dev])
        mnt.rmdir()


FILLER = '''
import os, tempfile
_KEEP = []
def _fill():
    for d in (".", tempfile.gettempdir()):  # files of 15 MiB (RLIMIT_FSIZE is 16 MiB) until full
        try:
            for i in range(40):
                with open(os.path.join(d, f"fill{i}"), "wb") as f:
                    f.write(b"x" * (15 << 20))
        except OSError:
            pass
    try:  # deleted files kept open: in no folder
        for i in range(8):
            f = open(f"u{i}", "wb")
            os.unlink(f"u{i}")
            _KEEP.append(f)
            f.write(b"x" * (15 << 20))
            f.flush()
    except OSError:
        pass
    try:  # data below a path longer than PATH_MAX
        for _ in range(20):
            os.mkdir("n" * 250)
            os.chdir("n" * 250)
        with open("deep", "wb") as f:
            f.write(b"x" * (15 << 20))
    except OSError:
        pass
_fill()
'''

DRIVER = """
import json, sys
from pathlib import Path
from flowtrack_course.grading.engine.jobs import ClassJob, StudentJob
from flowtrack_course.grading.engine.student import grade_student
from flowtrack_course.grading.grade import grade_class
from flowtrack_course.grading.sources import course_catalog
catalog = course_catalog()
ex = catalog.get(sys.argv[3])
if sys.argv[5] == "warm":  # one student, without grade_class's checks: fills the sandbox cache
    jobs = [StudentJob(p.name, p, Path(sys.argv[2]), (ex,)) for p in Path(sys.argv[1]).iterdir()]
    print(json.dumps([grade_student(job) for job in jobs]))
    sys.exit()
try:
    rows = grade_class(ClassJob(sys.argv[1], sys.argv[2], catalog=catalog, jobs=2, exercises=(ex,),
                                progress=False, allow_unsafe_sandbox=sys.argv[4] == "1"))
except Exception as exc:
    print(json.dumps({"refused": f"{type(exc).__name__}: {exc}"}))
else:
    print(json.dumps(rows))
"""


def _class(root: Path, names: list[str], attacker: str | None = None) -> Path:
    ex = get_exercise(EXERCISE)
    for name in names:
        (root / name).mkdir(parents=True)
        shutil.copy(source_notebook(ex), root / name / ex.notebook)
    if attacker:
        nb = json.loads((root / attacker / ex.notebook).read_text())
        cell = next(c for c in nb["cells"]
                    if c.get("metadata", {}).get("nbgrader", {}).get("grade_id") == "cv_transition")
        cell["source"] = FILLER + "".join(cell["source"])
        (root / attacker / ex.notebook).write_text(json.dumps(nb))
    os.chmod(root, 0o700)
    return root


def _grade(subs: Path, out: Path, unsafe: bool, warm: bool = False):
    args = [str(subs), str(out), EXERCISE, "1" if unsafe else "0", "warm" if warm else "class"]
    r = subprocess.run([sys.executable, "-c", DRIVER, *args],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


def _free(path: Path) -> tuple[int, int]:
    """(bytes an unprivileged user may still write, bytes root may) on the filesystem of ``path``."""
    st = os.statvfs(path)
    return st.f_bavail * st.f_frsize, st.f_bfree * st.f_frsize


def _entries(fs: Path, skip: set[str]) -> set[str]:
    out = set()
    for dirpath, dirnames, filenames in os.walk(fs):
        rel = Path(dirpath).relative_to(fs)
        if rel.parts and rel.parts[0] in skip:
            dirnames[:] = []
            continue
        out |= {str(rel / n) for n in (*dirnames, *filenames) if (rel / n).parts[0] not in skip}
    return out


@needs_loop
@pytest.mark.parametrize("mode", ["bwrap", "setpriv", "fallback"])
def test_a_disk_filler_on_a_small_filesystem_leaves_the_next_run_whole(mode, small_fs, monkeypatch,
                                                                       tmp_path, tmp_path_factory):
    fs, dev = small_fs
    full = get_exercise(EXERCISE).max_score
    use_sandbox_mode(mode, monkeypatch, tmp_path_factory)
    for d in ("cache", "tmp"):
        (fs / d).mkdir(mode=0o755 if d == "cache" else 0o700)
    monkeypatch.setenv("FLOWTRACK_SANDBOX_CACHE", str(fs / "cache"))
    monkeypatch.setenv("TMPDIR", str(fs / "tmp"))
    unsafe = mode == "fallback"  # grade refuses the fallback unless told

    # warm-up: the sandbox cache's prepared copies are made on the image
    warm = _grade(_class(tmp_path / "subs0", ["warm"]), fs / "out0", unsafe, warm=True)
    assert [r.get("score") for r in warm] == [full], warm
    # a ballast file of the grader's leaves 96 MiB: less than one student's disk limit (256 MiB)
    user_free, _ = _free(fs)
    with open(fs / "ballast", "wb") as f:
        os.posix_fallocate(f.fileno(), 0, user_free - 96 * MiB)
    before = _entries(fs, {"out0", "out1", "out2"})

    subs1 = _class(tmp_path / "subs1", ["ann", "mallory", "zoe"], attacker="mallory")
    if mode != "bwrap":
        # the students' work area shares the filesystem with the output, and the students could
        # take all of its free space: the grader refuses, saying why and what to do
        rows = _grade(subs1, fs / "out1", unsafe)
        assert "refused" in rows, rows
        assert "FLOWTRACK_SANDBOX_CACHE" in rows["refused"] and "reserve" in rows["refused"], rows
        assert not (fs / "out1" / "grades.csv").exists()
        # a root reservation of 64 MiB: the students (an unprivileged uid) cannot take it
        subprocess.run(["tune2fs", "-r", str(64 * MiB // 4096), dev], check=True, capture_output=True)

    rows = {r["student"]: r for r in _grade(subs1, fs / "out1", unsafe)}
    assert rows["ann"]["score"] == rows["zoe"]["score"] == full, rows
    # graded like anyone: its answer is right, so it earns that (its filler met ENOSPC), or 0 when
    # the sandbox stopped it at the disk limit; between the two only when a limit ended some tests
    # (on a loaded machine writing hundreds of MiB can outlast the first tests' time limit): the
    # feedback then names the limit
    assert "error" not in rows["mallory"] and 0.0 <= rows["mallory"]["score"] <= full, rows
    if 0.0 < rows["mallory"]["score"] < full:
        result = json.loads((fs / "out1" / "mallory" / "results.json").read_text())
        failed = [t["output"] for t in result["tests"] if t["status"] == "failed"]
        assert failed and all(re.search(r"timed out|limit|CPU time", o) for o in failed), failed
    # the next run, on the same filesystem: honest students in full
    subs2 = _class(tmp_path / "subs2", ["bob", "carol", "dan"])
    rows2 = {r["student"]: r for r in _grade(subs2, fs / "out2", unsafe)}
    assert all(r.get("score") == full for r in rows2.values()), rows2
    for out, names in ((fs / "out1", ["ann", "mallory", "zoe"]), (fs / "out2", ["bob", "carol", "dan"])):
        lines = (out / "grades.csv").read_text().splitlines()
        assert [ln.split(",")[0] for ln in lines[1:]] == names
        assert (out / "gradebook.db").stat().st_size > 0
        assert all((out / s / "results.json").is_file() for s in names)
    # nothing of the students is left on the filesystem: outside the outputs it is as before
    assert _entries(fs, {"out0", "out1", "out2"}) == before
    assert list((fs / "cache" / f"flowtrack-sandbox-{os.geteuid()}" / "work").iterdir()) == []
    if mode == "bwrap":  # not a byte of the filler reached the image
        assert _free(fs)[0] > 80 * MiB


def test_the_reserve_check_needs_a_shared_filesystem_and_too_little_room(tmp_path):
    from grading_sandbox.isolation import disk_reserve_problem

    work, out = tmp_path / "work", tmp_path / "out" / "not-yet"  # out: its nearest existing ancestor
    work.mkdir()
    st = os.statvfs(tmp_path)
    room = st.f_bavail * st.f_frsize
    assert disk_reserve_problem([work], [out], students_max=0, reserve=0) == ""
    problem = disk_reserve_problem([work], [out], students_max=room + (1 << 40), reserve=room + (1 << 40))
    assert "FLOWTRACK_SANDBOX_CACHE" in problem and str(out) in problem
    # another filesystem (procfs) than the students' never needs a reserve
    assert disk_reserve_problem([work], ["/proc/self"], students_max=1 << 60, reserve=1 << 60) == ""
