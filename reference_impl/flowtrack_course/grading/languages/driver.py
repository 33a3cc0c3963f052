"""The driver the sandboxed child executes for an answer in another language (trusted code, run inside).

:func:`driver_cell` returns the Python source of the one "cell" a language exercise hands to
:class:`grading_sandbox.Sandbox`. The source carries the student's file and the
grader's own harness files as data; executing it only defines ``run_cases``. On the first call it
writes the files into the sandbox's home directory, runs the build commands (each under the
compile time limit; a failed build raises ``RuntimeError`` holding the compiler's message, so the
test's feedback shows it) and then runs the program once per call on a vectors file holding the
call's cases (inputs only: expected values never enter the sandbox), under the run time limit
and with its output capped. The program's ``OUTPUT <id> <json>`` / ``ERROR <id> <message>``
lines become the call's result: ``{id: {"ok": bool, "value": outputs | None, "error": str}}``.

A command word ``@PYTHON@`` stands for the sandbox's own Python interpreter, which then gets the
child's module path in ``FT_PYTHONPATH``. A harness written in Python (Mathics3's) may instead run
in the child itself (``inproc``): the child is then the program, under the sandbox's per-batch CPU,
memory and wall-clock limits. Everything the program does happens
inside the sandbox (its uid, namespaces and resource limits
apply to the compiler and to the program, which are the child's descendants); on a timeout the
driver kills the program's whole process group.
"""

from __future__ import annotations

import base64
import json

__all__ = ["driver_cell"]

_TEMPLATE = r'''
import base64 as _b64, json as _json, os as _os, signal as _signal, subprocess as _sp, sys as _sys

_SPEC = _json.loads(@SPEC@)
_STATE = {}


def _ft_exec(cmd, timeout, out_path, what):
    with open(out_path, "wb") as out:
        cmd = [_sys.executable if c == "@PYTHON@" else c for c in cmd]
        env = {**_os.environ, **_SPEC["env"], "FT_PYTHONPATH": _os.pathsep.join(_sys.path)}
        proc = _sp.Popen(cmd, stdin=_sp.DEVNULL, stdout=out, stderr=_sp.STDOUT, start_new_session=True,
                         env=env)
        try:
            rc = proc.wait(timeout=timeout)
        except _sp.TimeoutExpired:
            rc = None
        finally:
            try:
                _os.killpg(proc.pid, _signal.SIGKILL)
            except OSError:
                pass
            proc.wait()
    with open(out_path, "rb") as fh:
        text = fh.read(_SPEC["output_bytes"] + 1)
    too_long = len(text) > _SPEC["output_bytes"]
    text = text[: _SPEC["output_bytes"]].decode("utf-8", "replace")
    if rc is None:
        raise RuntimeError(f"{what} timed out after {timeout:g} s")
    if too_long:
        raise RuntimeError(f"{what} printed more than {_SPEC['output_bytes']} bytes")
    return rc, text


def _ft_build():
    if "error" in _STATE:
        raise RuntimeError(_STATE["error"])
    if _STATE.get("built"):
        return
    root = _os.path.join(_os.getcwd(), "build")
    _os.makedirs(root, exist_ok=True)
    for rel, text in _SPEC["files"].items():
        with open(_os.path.join(root, rel), "w", encoding="utf-8") as fh:
            fh.write(text)
    for rel, data in _SPEC["blobs"].items():
        with open(_os.path.join(root, rel), "wb") as fh:
            fh.write(_b64.b64decode(data))
    _os.chdir(root)
    for cmd in _SPEC["build"]:
        rc, text = _ft_exec(cmd, _SPEC["compile_seconds"], "build.log", "the build")
        if rc != 0:
            lines = text.strip().splitlines()
            head = "build failed (" + cmd[0] + f", exit {rc}):\n"
            _STATE["error"] = head + "\n".join(lines[:40])
            raise RuntimeError(_STATE["error"])
    _STATE["built"] = True


def _ft_inproc(doc):
    """The harness run in this process (Mathics3: its interpreter may already be loaded here)."""
    spec = _SPEC["inproc"]
    ns = _STATE.get("inproc")
    if ns is None:
        path = _os.path.join(_os.getcwd(), spec["file"])
        ns = {"__name__": "ft_inproc", "__file__": path}
        with open(path, encoding="utf-8") as fh:
            exec(compile(fh.read(), path, "exec"), ns)
        _STATE["inproc"] = ns
    text = ns[spec["function"]](*spec["args"], doc)
    if not isinstance(text, str):
        raise RuntimeError("the harness returned no text")
    if len(text) > _SPEC["output_bytes"]:
        raise RuntimeError(f"the program printed more than {_SPEC['output_bytes']} bytes")
    return 0, text


def run_cases(doc):
    """Run the program on the vectors document ``doc``; ``{case id: {"ok", "value", "error"}}``."""
    _ft_build()
    if _SPEC.get("inproc"):
        rc, text = _ft_inproc(doc)
    else:
        with open("cases.json", "w", encoding="utf-8") as fh:
            _json.dump(doc, fh)
        rc, text = _ft_exec(_SPEC["run"], _SPEC["run_seconds"], "run.log", "the program")
    results = {}
    for line in text.splitlines():
        parts = line.split(" ", 2)
        if len(parts) == 3 and parts[0] == "OUTPUT" and parts[1] not in results:
            try:
                value = _json.loads(parts[2])
            except ValueError:
                results[parts[1]] = {"ok": False, "value": None, "error": "unreadable output"}
                continue
            ok = isinstance(value, dict)
            err = "" if ok else "not an object"
            results[parts[1]] = {"ok": ok, "value": value if ok else None, "error": err}
        elif len(parts) >= 2 and parts[0] == "ERROR" and parts[1] not in results:
            err = (parts[2] if len(parts) > 2 else "")[:500]
            results[parts[1]] = {"ok": False, "value": None, "error": err}
    if not results:
        tail = " | ".join(text.strip().splitlines()[-5:])[:800]
        raise RuntimeError(f"the program printed no result (exit {rc}): {tail}")
    return results
'''


def driver_cell(
    *,
    files: dict[str, str],
    blobs: dict[str, bytes],
    build: list[list[str]],
    run: list[str],
    env: dict[str, str],
    compile_seconds: float,
    run_seconds: float,
    output_bytes: int,
    inproc: dict | None = None,
) -> str:
    """The Python source of the driver cell (see the module docstring); every argument is data.

    ``inproc`` (``{"file", "function", "args"}``): instead of running ``run``, load the harness
    ``file`` (one of ``files``) into this process once and call ``function(*args, doc)``, which
    returns the program's output lines as text (Mathics3, whose interpreter a zygote may have
    loaded before forking this child).
    """
    spec = {
        "inproc": dict(inproc) if inproc else None,
        "files": dict(files),
        "blobs": {k: base64.b64encode(v).decode("ascii") for k, v in blobs.items()},
        "build": [list(map(str, c)) for c in build],
        "run": list(map(str, run)),
        "env": dict(env),
        "compile_seconds": float(compile_seconds),
        "run_seconds": float(run_seconds),
        "output_bytes": int(output_bytes),
    }
    return _TEMPLATE.replace("@SPEC@", repr(json.dumps(spec)))
