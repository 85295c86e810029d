"""``python -m app`` is the ``c2n`` command (``run``, the console script's too): c2n's modules load
(0.7 s of numpy, rich, python-can…) with Ctrl-C ending the command as at any other time — one
line, exit 130 — not with the traceback of whichever import it landed in."""

import sys


def run() -> None:
    try:
        from app.cli import entry
    except KeyboardInterrupt:
        sys.stderr.write("c2n: interrupted\n")
        exec("")  # the interrupt caught: CPython's flag cleared, as app.cli.entry does (its comment)
        raise SystemExit(130) from None
    entry()


if __name__ == "__main__":
    run()
