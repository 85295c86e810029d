"""Issue 39, the last holes: a folder c2n makes is made whole or not at all. A pack or a campaign
interrupted midway leaves nothing under its name (and nothing that blocks the next run); two
``live`` started in one second record into two folders; a refused scheduler leaves no trace."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.live_process import foreground
from tests.simulated import REPO
from tests.test_reliability_inputs import run_cli

# four drives: the run is still writing the later ones when the first is there (two finished
# before the signal on a loaded machine)
KINDS = {
    "pack": (["--pack", "4", "--quick", "--workers", "1"], "case_001/drive.blf"),
    "campaign": (["--campaign", "4", "--workers", "1"], "logs/s00*.blf"),
}


def _start(out: Path, kind: str) -> subprocess.Popen[str]:
    options, _ = KINDS[kind]
    return subprocess.Popen(
        [sys.executable, "-m", "app", "simulate", *options, "--out", str(out)],
        cwd=REPO,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=foreground,
    )


def _children(pid: int) -> list[int]:
    """The processes ``pid`` made (Linux's /proc; elsewhere none are looked for)."""
    listed = Path(f"/proc/{pid}/task/{pid}/children")
    return [int(p) for p in listed.read_text().split()] if listed.exists() else []


def _alive(pid: int) -> bool:
    """Running, or stopped: not gone and not a zombie waiting for its parent's reaper."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _first_file(child: subprocess.Popen[str], folder: Path, pattern: str) -> None:
    """Wait until the run has written its first drive (wherever it writes it)."""
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and child.poll() is None:
        if list(folder.glob(f"*/{pattern}")) or list(folder.glob(f".*/{pattern}")):
            return
        time.sleep(0.05)
    raise AssertionError(f"no drive written before the run ended ({child.poll()})")


@pytest.mark.parametrize("kind", KINDS)
def test_an_interrupted_pack_or_campaign_leaves_nothing_under_its_name(tmp_path: Path, kind: str) -> None:
    out = tmp_path / f"[{kind}] 1"  # brackets: glob's own characters, in a name c2n must escape
    (tmp_path / "mine.txt").write_text("my notes")
    child = _start(out, kind)
    try:
        _first_file(child, tmp_path, KINDS[kind][1])
        child.send_signal(signal.SIGINT)
        _, err = child.communicate(timeout=120)
    finally:
        child.kill()
    assert child.returncode == 130 and "Traceback" not in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.txt"]  # no half folder, no temporary
    # a killed run (SIGKILL cannot be caught) leaves its temporary: the next run clears it
    child = _start(out, kind)
    try:
        _first_file(child, tmp_path, KINDS[kind][1])
        workers = _children(child.pid)
        child.kill()
        child.wait(timeout=30)
    finally:
        child.kill()
    # its workers end with it (a campaign's worker was left blocked on its task pipe for good)
    deadline = time.monotonic() + 30
    while [pid for pid in workers if _alive(pid)] and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not [pid for pid in workers if _alive(pid)]
    assert not out.exists()
    left = [p.name for p in tmp_path.iterdir() if p.name != "mine.txt"]
    assert len(left) == 1 and left[0].startswith(f".{out.name}.partial-{child.pid}-"), left
    code, _, err = run_cli(["simulate", *KINDS[kind][0], "--out", str(out)])
    assert code == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([out.name, "mine.txt"])
    assert len(list(out.glob(KINDS[kind][1].replace("case_001", "case_00*")))) == 4
    assert (out / "sealed" / "truth.json").is_file() and (tmp_path / "mine.txt").read_text() == "my notes"


def test_a_pack_s_folder_filled_by_someone_else_meanwhile_is_left_as_it_is(tmp_path: Path) -> None:
    """The folder is put in place by one rename, which the system refuses over a folder that is
    no longer empty: the user's file stays, the pack is not half-merged into it."""
    from app.sim.pack import write_pack
    from app.sim.standard import QUICK_PLAN

    out = tmp_path / "pack"
    out.mkdir()

    def meanwhile(case: object) -> None:
        (out / "mine.txt").write_text("put here while the pack was written")

    with pytest.raises(Exception, match="was filled while c2n wrote"):
        write_pack(out, 1, 3, plan=QUICK_PLAN, workers=1, on_case=meanwhile, realistic=False)
    assert [p.name for p in tmp_path.iterdir()] == ["pack"] and os.listdir(out) == ["mine.txt"]


def test_sessions_begun_in_one_second_claim_a_folder_each_and_enter_none_already_there(
    tmp_path: Path,
) -> None:
    import datetime
    import threading

    from app.cli.live import session_folder

    second = datetime.datetime(2026, 11, 27, 1, 2, 3)
    stamp = "2026-11-27_010203"
    (tmp_path / stamp).mkdir()
    (tmp_path / stamp / "frames.log").write_text("an older session's")
    (tmp_path / f"{stamp}-2").write_text("a file of that name")
    claimed: list[Path] = []
    threads = [
        threading.Thread(target=lambda: claimed.append(session_folder(tmp_path, lambda: second)))
        for _ in range(8)
    ]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert sorted(p.name for p in claimed) == sorted(f"{stamp}-{n}" for n in range(3, 11))
    assert all(p.is_dir() and not any(p.iterdir()) for p in claimed)
    assert (tmp_path / stamp / "frames.log").read_text() == "an older session's"
    assert os.listdir(tmp_path / stamp) == ["frames.log"]
    assert (tmp_path / f"{stamp}-2").read_text() == "a file of that name"


def test_a_live_session_records_into_the_folder_it_claimed(tmp_path: Path) -> None:
    """The recorder is handed the claimed (empty) folder; one it cannot record in is not left."""
    from app.cli.live import _recorder, session_folder
    from app.config import load_config
    from app.errors import C2nError

    recorder = _recorder(tmp_path, load_config(), ".log")
    recorder.close()
    assert [p.name for p in tmp_path.iterdir()] == [recorder.folder.name]
    assert (recorder.folder / "frames.log").exists() and (recorder.folder / "events.csv").exists()
    with pytest.raises(C2nError, match="raw format"):
        _recorder(tmp_path / "other", load_config(), ".txt")
    assert list((tmp_path / "other").iterdir()) == []
    assert session_folder(tmp_path / "new" / "deeper").parent == tmp_path / "new" / "deeper"


def test_a_refused_scheduler_leaves_the_output_location_as_it_was(tmp_path: Path) -> None:
    import socket

    manifest = tmp_path / "m.csv"
    manifest.write_text("log,tyre_set\nd.log,A\n")
    (tmp_path / "d.log").write_text("(0.000000) can0 123#0102\n")
    kept = tmp_path / "kept"  # an empty folder the user made for it: stays, empty
    kept.mkdir()
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))  # bound, not listening: the connection is refused
        scheduler = f"tcp://127.0.0.1:{s.getsockname()[1]}"
        for out in (None, tmp_path / "new" / "deeper", kept):
            before = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*"))
            argv = ["campaign", str(manifest), "--scheduler", scheduler]
            code, _, err = run_cli([*argv, "--out", str(out)] if out else argv)
            assert code == 1 and "no Dask scheduler answers" in err, err
            assert sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*")) == before, out
    assert kept.is_dir()


def test_a_pack_into_the_empty_working_folder_fills_it_in_place(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``--out .``: the folder a shell stands in is filled, not renamed away under it."""
    here = tmp_path / "here"
    here.mkdir()
    monkeypatch.chdir(here)
    code, _, err = run_cli(["simulate", "--pack", "1", "--quick", "--workers", "1", "--out", "."])
    assert code == 0, err
    assert sorted(os.listdir(here)) == ["case_001", "sealed"] and os.listdir(tmp_path) == ["here"]
    assert Path.cwd() == here and (here / "case_001" / "drive.blf").stat().st_size > 0


def _without_root_s_override() -> list[str]:
    """A prefix that runs a command without root's licence to write anywhere (none: not root)."""
    if os.geteuid() != 0:
        return []
    return ["setpriv", "--bounding-set", "-dac_override,-dac_read_search,-fowner", "--"]


READ_ONLY = {
    "pack": ["simulate", "--pack", "1", "--quick", "--out", "{ro}/p"],
    "campaign": ["simulate", "--campaign", "1", "--out", "{ro}/c"],
    "live": ["live", "-i", "virtual", "--duration", "1", "--record", "{ro}/sessions"],
    "campaign --scheduler": ["campaign", "{manifest}", "--out", "{ro}/o", "--scheduler", "tcp://127.0.0.1:9"],
}


@pytest.mark.parametrize("command", READ_ONLY)
def test_a_read_only_parent_is_one_line_and_nothing_is_made(tmp_path: Path, command: str) -> None:
    ro = tmp_path / "ro"
    ro.mkdir()
    (tmp_path / "m.csv").write_text("log,tyre_set\nd.log,A\n")
    (tmp_path / "d.log").write_text("(0.000000) can0 123#0102\n")
    ro.chmod(0o555)
    argv = [arg.format(ro=ro, manifest=tmp_path / "m.csv") for arg in READ_ONLY[command]]
    done = subprocess.run(
        [*_without_root_s_override(), sys.executable, "-m", "app", *argv],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 1 and done.stderr.count("\n") == 1, done.stderr
    assert "Permission denied" in done.stderr and "Traceback" not in done.stderr
    assert os.listdir(ro) == []


def test_two_packs_to_the_same_new_folder_at_once_give_one_whole_pack(tmp_path: Path) -> None:
    out = tmp_path / "pack"
    children = [_start(out, "pack") for _ in range(2)]
    try:
        errors = [child.communicate(timeout=300)[1] for child in children]
    finally:
        for child in children:
            child.kill()
    assert sorted(child.returncode for child in children) == [0, 1], errors
    refused = errors[[child.returncode for child in children].index(1)]
    assert refused.count("\n") == 1 and ("was filled while c2n wrote" in refused or "holds files" in refused)
    assert os.listdir(tmp_path) == ["pack"]  # no temporary left
    assert sorted(os.listdir(out)) == [f"case_00{k}" for k in range(1, 5)] + ["sealed"]


def test_an_export_into_the_working_folder_is_one_line_not_the_folder_swapped_away(
    drive_log: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    here = tmp_path / "here"
    here.mkdir()
    monkeypatch.chdir(here)
    code, _, err = run_cli(["export", str(drive_log), "--no-plots", "--format", "csv", "--out", "."])
    assert code == 1 and err.count("\n") == 1 and "is the folder c2n runs in" in err, err
    assert Path.cwd().exists() and os.listdir(here) == [] and os.listdir(tmp_path) == ["here"]
