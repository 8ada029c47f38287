"""Run the ``fricenv`` command in-process for a test: its exit status and captured output."""

from __future__ import annotations

from fricenv.cli import main


def run(capsys, *argv: str) -> tuple[int, str, str]:
    """``fricenv *argv`` with pytest's ``capsys``: (exit status, stdout, stderr); a usage
    error's ``SystemExit`` counts as its status."""
    try:
        code = main(list(argv))
    except SystemExit as e:
        code = e.code if isinstance(e.code, int) else 1
    out = capsys.readouterr()
    return code, out.out, out.err
