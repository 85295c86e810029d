"""A quick start: ``c2n --help`` and every ``c2n <command> --help`` load no heavy library."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from app.cli import COMMANDS, main
from tests.simulated import REPO

# what the commands load when they run (numpy is light enough, but --help has no use for it either)
HEAVY = ("asammdf", "pandas", "scipy", "numba", "pyarrow", "matplotlib", "filterpy", "cantools", "can")
HEAVY += ("numpy", "threadpoolctl", "vehiclemodels")

_CHILD = """
import contextlib, io, json, sys
from app.cli import main
helps = [["--help"]] + [[name, "--help"] for name in sys.argv[1:]]
with contextlib.redirect_stdout(io.StringIO()) as out:
    codes = [main(argv) for argv in helps]
print(json.dumps({"codes": codes, "chars": len(out.getvalue()), "modules": sorted(sys.modules)}))
"""


def command_names() -> list[str]:
    return [command.__name__.rpartition(".")[2].replace("_", "-") for command in COMMANDS]


def test_help_of_c2n_and_of_every_command_loads_no_heavy_library() -> None:
    names = command_names()
    child = subprocess.run(
        [sys.executable, "-c", _CHILD, *names], capture_output=True, text=True, cwd=REPO, check=True
    )
    seen = json.loads(child.stdout)
    assert seen["codes"] == [0] * (len(names) + 1), child.stderr
    assert seen["chars"] > 200 * len(names)  # the help texts were printed
    loaded = {name.partition(".")[0] for name in seen["modules"]}
    assert sorted(loaded & set(HEAVY)) == []


def test_the_choices_named_for_help_are_the_ones_the_writers_take() -> None:
    from app.cli import export
    from app.sinks import channels

    assert export.FORMATS == channels.FORMATS


# -- a lean install: the core without the extras ------------------------------------------------------

EXTRAS = ("asammdf", "pandas", "pyarrow", "matplotlib", "filterpy", "vehiclemodels")  # not in c2n's core

_LEAN_CHILD = """
import sys
for name in sys.argv[1].split(","):
    sys.modules[name] = None  # as if not installed: importing it raises ModuleNotFoundError
from app.cli import main
sys.exit(main(sys.argv[2:]))
"""


def test_analyze_of_a_blf_log_works_without_any_extra(drive_log: Path) -> None:
    child = subprocess.run(
        [sys.executable, "-c", _LEAN_CHILD, ",".join(EXTRAS), "analyze", str(drive_log)],
        capture_output=True,
        text=True,
        cwd=REPO,
    )
    assert child.returncode == 0, child.stderr
    assert "C2n" in child.stdout and "Traceback" not in child.stderr


READING_MF4 = "reading .mf4 logs needs asammdf: pip install 'c2n[mf4]'"


@pytest.mark.parametrize(
    ("missing", "argv", "line"),
    [
        (
            "asammdf",
            ["analyze", "{dir}/drive.mf4"],
            "reading .mf4 logs needs asammdf: pip install 'c2n[mf4]'",
        ),
        ("asammdf", ["replay", "{dir}/drive.mf4"], "reading .mf4 logs needs asammdf: pip install 'c2n[mf4]'"),
        (
            "asammdf",
            ["simulate", "--out", "{dir}/sim.mf4"],
            "writing .mf4 logs needs asammdf: pip install 'c2n[mf4]'",
        ),
        (
            "pyarrow",
            ["export", "{dir}/drive.blf", "--format", "parquet", "--no-plots"],
            "writing Parquet channels needs pyarrow: pip install 'c2n[export]'",
        ),
        (
            "matplotlib",
            ["export", "{dir}/drive.blf", "--format", "csv"],
            "drawing the plots needs matplotlib: pip install 'c2n[export]' (or --no-plots)",
        ),
        (
            "matplotlib",
            ["gap", "{dir}/drive.blf", "--report", "{dir}/gap.html"],
            "drawing the residual maps of --report needs matplotlib: pip install 'c2n[export]'",
        ),
    ],
)
def test_a_command_that_needs_a_missing_extra_says_which_in_one_line(
    missing: str,
    argv: list[str],
    line: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    for name in ("drive.mf4", "drive.blf"):
        (tmp_path / name).write_bytes(b"not read: the library is missing first")
    monkeypatch.setitem(sys.modules, missing, None)  # as if not installed
    code = main([arg.replace("{dir}", str(tmp_path)) for arg in argv])
    err = capsys.readouterr().err
    assert (code, err) == (1, f"c2n: error: {line}\n")
    assert not (tmp_path / "sim.mf4").exists() and not (tmp_path / "gap.html").exists()


_LIVE_CHILD = """
import json, os, sys, threading, time
from app.cli import main
import app.cli.live as live
own = live.import_python_can

def then_send():  # frames on the bus once c2n live has imported python-can its way
    own()
    import can
    import app.pipeline
    def first(self, record):
        before = sorted(sys.modules)
        import asammdf  # still there for whatever needs it later
        print(json.dumps({"before": before, "asammdf": asammdf.__version__}), flush=True)
        os._exit(0)
    app.pipeline.Pipeline.take = first
    def send():
        with can.Bus(interface="virtual", channel=sys.argv[1]) as bus:
            while True:
                bus.send(can.Message(arbitration_id=0x7E5, is_extended_id=False, data=bytes(8)))
                time.sleep(0.002)
    threading.Thread(target=send, daemon=True).start()

live.import_python_can = then_send
main(["live", "-i", "virtual", "-c", sys.argv[1], "--no-record", "--duration", "30"])
"""


def test_live_reaches_its_first_frame_without_python_can_s_mf4_libraries(tmp_path: Path) -> None:
    """python-can imports asammdf and pandas for its MF4 classes, half of `c2n live`'s start: the
    live session, which records .log/.asc/.blf, imports python-can without them; asammdf itself
    still imports afterwards."""
    child = subprocess.run(
        [sys.executable, "-c", _LIVE_CHILD, f"startup-{tmp_path.name}"],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=120,
    )
    seen = json.loads(child.stdout.strip().splitlines()[-1])
    loaded = {name.partition(".")[0] for name in seen["before"]}
    assert {"can", "cantools", "numba"} <= loaded  # the bus, the DBCs and the filter are up
    assert not loaded & {"asammdf", "pandas"}
    assert seen["asammdf"]  # and importable after: not blocked for good
