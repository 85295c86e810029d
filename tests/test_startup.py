"""A quick start: ``c2n --help`` and every ``c2n <command> --help`` load no heavy library."""

import json
import subprocess
import sys

from app.cli import COMMANDS
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
    from app.cli import export, live
    from app.sinks import channels, recorder

    assert live.RAW_FORMATS == recorder.RAW_FORMATS
    assert export.FORMATS == channels.FORMATS
