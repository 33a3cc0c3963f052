"""Project invariants: the set-up commands, CI entry point and notebook hygiene."""

import json
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_readme_gives_the_two_setup_commands():
    text = (ROOT / "README.md").read_text()
    assert "make demo" in text and "make test" in text


def test_ci_runs_the_readme_test_command():
    lines = [ln.strip() for ln in (ROOT / ".ci/run").read_text().splitlines()]
    assert "make test" in lines


def test_no_committed_notebook_has_outputs():
    tracked = subprocess.run(
        ["git", "ls-files", "*.ipynb"], cwd=ROOT, capture_output=True, text=True, check=False
    ).stdout.split()
    bad = []
    for rel in tracked:
        nb = json.loads((ROOT / rel).read_text())
        if any(c.get("outputs") for c in nb.get("cells", []) if c.get("cell_type") == "code"):
            bad.append(rel)
    assert not bad, f"notebooks with committed outputs: {bad}"


def test_cli_help_on_every_subcommand():
    from flowtrack.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    assert sub.choices, "no sub-commands"
    for name, p in sub.choices.items():
        assert p.format_help().startswith("usage: flowtrack " + name)
