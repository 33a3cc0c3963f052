"""How a failed call is told: the one formatter of student exceptions, and the words a hidden test
may show of any error.

Two readers see an error, and they may see different things:

* the student's **public** feedback shows the text itself: :func:`exception_text` formats an
  exception raised by student code, the same way wherever the code ran (the sandboxed child, which
  loads this file by path before any student code, and an in-process stand-in such as a notebook's
  own grading run or a test's fake sandbox), so that what the tests see is what students see;
* a **hidden** test's feedback may not carry a single character the student's code chose, because
  that code saw the hidden inputs (``raise ValueError(f"\\n{dt}")`` would print them, and so would
  an exit status ``os._exit(int(dt * 100))`` or a class named after them). :func:`category` turns
  any error text, whoever wrote it, into one sentence of a fixed list: the sandbox's own reasons
  (a limit, a crash, an exit; without numbers or signal names), or ``your code raised X`` where
  ``X`` is one of the exception types of :data:`EXCEPTIONS`, else ``your code raised an
  exception``. The sandbox's replies are untrusted (the child may forge any text), so the category
  is read from the text and never copied from it: what the student can choose is which sentence of
  the list, no more (see the threat model in the package's docstring).

Imports the standard library only (the child loads it).

Examples
--------
>>> exception_text(ValueError("\\n0.123"))
'ValueError: \\n0.123'
>>> category("ValueError: \\n0.123"), category("Leak: 0.5"), category("crashed (SIGSEGV)")
('your code raised ValueError', 'your code raised an exception', 'crashed (killed by a signal)')
>>> category("the process exited (sys.exit / os._exit) with status 55")
'the process exited (sys.exit, os._exit or a fatal error)'
"""

from __future__ import annotations

import re
import traceback

__all__ = ["EXCEPTIONS", "MAX_TEXT", "category", "exception_text", "missing_function", "not_plain"]

#: the longest error text the sandbox reports
MAX_TEXT = 2000

#: the exception types a hidden test names (anything else is "an exception")
EXCEPTIONS = frozenset({
    "ArithmeticError", "AssertionError", "AttributeError", "FloatingPointError", "ImportError",
    "IndexError", "KeyError", "LinAlgError", "LookupError", "ModuleNotFoundError", "NameError",
    "NotImplementedError", "OverflowError", "RecursionError", "RuntimeError", "TypeError",
    "UnboundLocalError", "ValueError", "ZeroDivisionError",
})


def exception_text(exc: BaseException, *, cell: bool = False) -> str:
    """What a call (or, with ``cell``, an answer cell) that raised ``exc`` reports: the exception's
    type and message as Python prints them (``format_exception_only``), cut to :data:`MAX_TEXT`;
    memory, exits and recursion in a fixed form."""
    if isinstance(exc, SystemExit):
        return "the cell called sys.exit()" if cell else "the process exited (sys.exit / os._exit)"
    if isinstance(exc, MemoryError) and not cell:
        return "ran out of memory (MemoryError)"
    if isinstance(exc, RecursionError) and not cell:
        return "RecursionError: maximum recursion depth exceeded"
    try:
        text = "".join(traceback.format_exception_only(type(exc), exc)).strip()
    except Exception:  # a student's __str__ that raises
        text = type(exc).__name__
    return text[:MAX_TEXT]


def missing_function(name: str) -> str:
    """The error of a call of a function the cells did not define."""
    return f"NameError: there is no function named {name!r} (was it renamed or deleted?)"


def not_plain(what: str) -> str:
    """The error of a call whose result is not plain data (``what``: why, e.g. ``returned a set``)."""
    return f"TypeError: {what}"


# (pattern at the start of the text, sentence): the first that matches wins
_SENTENCES = tuple((re.compile(p), s) for p, s in (
    (r"timed out", "timed out (the test's time limit was exceeded)"),
    (r"used more than .* of CPU time", "used more than its CPU time limit"),
    (r"wrote a file larger than the limit", "wrote a file larger than the limit"),
    (r"ran out of memory", "ran out of memory"),
    (r"was killed", "was killed (it ran out of memory or exceeded a limit)"),
    (r"crashed", "crashed (killed by a signal)"),
    (r"the (process exited|cell called sys\.exit)",
     "the process exited (sys.exit, os._exit or a fatal error)"),
    (r"the process closed its reply channel", "the process closed its reply channel"),
    (r"the result is larger than the output limit", "the result is larger than the output limit"),
    (r"(created more than|wrote more than) .*the disk limit|.*: the disk limit cannot be checked",
     "exceeded the disk limit"),
    (r"the sandbox could not start", "the sandbox could not start (not your code: tell your instructor)"),
    (r"the sandbox (sent|is not running)|the zygote", "the sandbox sent no valid reply"),
    (r"the result could not be encoded", "the result could not be encoded"),
    (r"NameError: there is no function named ", "the function is not defined (was it renamed or deleted?)"),
    (r"TypeError: (returned |the result is nested|a returned dict|an array of dtype|dict keys)",
     "the result is not plain data (numbers, lists or numpy arrays)"),
    (r"NotImplementedError\b", "NotImplementedError: the function is not implemented yet"),
))
_EXCEPTION = re.compile(r"([A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*)*)(?::|$)")


def category(text: str) -> str:
    """The sentence a hidden test shows for the error ``text`` (see the module docstring): always
    one of a fixed list, whatever ``text`` holds.

    >>> category("numpy.linalg.LinAlgError: Singular matrix"), category("")
    ('your code raised LinAlgError', 'the call failed')
    """
    text = str(text or "").strip()
    if text.startswith("Traceback (most recent call last):"):  # a whole traceback: its exception
        lines = [ln for ln in text.splitlines()[1:] if ln.strip() and not ln.startswith(" ")]
        text = "\n".join(lines)
    for pattern, sentence in _SENTENCES:
        if pattern.match(text):
            return sentence
    first = text.splitlines()[0] if text else ""
    m = _EXCEPTION.match(first)
    if m:
        name = m.group(1).rsplit(".", 1)[-1]
        return f"your code raised {name}" if name in EXCEPTIONS else "your code raised an exception"
    return "the call failed"
