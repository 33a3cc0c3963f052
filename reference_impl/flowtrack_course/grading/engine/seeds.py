"""Seeds of the tests' inputs: fixed for public tests, per student (keyed by the instructor's
secret) for hidden ones.
"""

from __future__ import annotations

import hashlib
import hmac

__all__ = ["MIN_SECRET_BYTES", "SECRET_BYTES", "public_seed", "read_secret", "secret_id", "student_seed"]


def student_seed(student: str, exercise: str, test: str, secret: bytes | None = None) -> int:
    """A stable 63-bit seed for one student's inputs of one test.

    Without ``secret`` it is sha256 of the names, which anyone holding the course package can
    recompute: a student could then draw their own hidden inputs, run the reference outside the
    sandbox and hard-code the answers. With the instructor's ``secret`` (see :func:`read_secret`)
    it is HMAC-SHA256 keyed by it, unpredictable without the key and still reproducible by the
    instructor.

    >>> student_seed("ana", "ex01", "t") == student_seed("ana", "ex01", "t")
    True
    >>> student_seed("ana", "ex01", "t") != student_seed("ana", "ex01", "t", secret=b"k" * 32)
    True
    """
    message = f"{student}\0{exercise}\0{test}".encode()
    if secret is None:
        digest = hashlib.sha256(message).digest()
    else:
        digest = hmac.new(_check_secret(secret), message, hashlib.sha256).digest()
    return int.from_bytes(digest[:8], "little") >> 1


def public_seed(exercise_id: str, test_name: str) -> int:
    """The fixed seed of a public test (the same for every student, in ``check``, ``grade`` and the
    notebooks' in-process run).

    >>> public_seed("ex01", "t") == student_seed("<public>", "ex01", "t")
    True
    """
    return student_seed("<public>", exercise_id, test_name)


SECRET_BYTES = 32  # what read_secret(create=True) writes; at least MIN_SECRET_BYTES are required
MIN_SECRET_BYTES = 16


def _check_secret(secret: bytes) -> bytes:
    if not isinstance(secret, bytes):
        raise TypeError(f"secret must be bytes, got {type(secret).__name__}")
    if len(secret) < MIN_SECRET_BYTES:
        raise ValueError(f"secret must hold at least {MIN_SECRET_BYTES} bytes, got {len(secret)}")
    return secret


def secret_id(secret: bytes | None) -> str:
    """A fingerprint of ``secret`` (``""`` for none): tells grading runs apart, reveals nothing."""
    if secret is None:
        return ""
    return hashlib.sha256(b"flowtrack seed key\0" + _check_secret(secret)).hexdigest()[:16]


def read_secret(path, *, create: bool = False) -> bytes:
    """The instructor's seed key from the file ``path``; with ``create``, a new random one if missing.

    A created file holds :data:`SECRET_BYTES` random bytes (``secrets.token_bytes``) and is readable
    by its owner only. Keep it next to the course, out of the students' release and out of version
    control shared with students: the same file must be used for every grading run of a class
    (hidden inputs, hence scores, depend on it).

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist and ``create`` is false.
    ValueError
        The file holds fewer than :data:`MIN_SECRET_BYTES` bytes.
    """
    import os
    import secrets
    from pathlib import Path

    path = Path(path)
    if create and not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "wb") as fh:
            fh.write(secrets.token_bytes(SECRET_BYTES))
    if not path.is_file():
        raise FileNotFoundError(f"secret file: no such file: {path}")
    data = path.read_bytes()
    if len(data) < MIN_SECRET_BYTES:
        raise ValueError(
            f"secret file {path} must hold at least {MIN_SECRET_BYTES} bytes, got {len(data)} "
            "(create one with: head -c 32 /dev/urandom > FILE)"
        )
    return data
