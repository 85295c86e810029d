"""A `c2n live` process with its own traffic, for the crash tests (python-can's virtual bus
reaches only buses in the same process).

    python tests/live_child.py CHANNEL RECORD_DIR SENT_FILE RAW_FORMAT

Runs `c2n live -i virtual -c CHANNEL --record RECORD_DIR`; once the session folder exists, a
thread sends the frames of a simulated drive, paced at about 2 kHz, and after each send appends
"index monotonic_time" to SENT_FILE (unbuffered), so the test knows what was sent before it killed
the process.
"""

import sys
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import can  # noqa: E402

from app.cli import main  # noqa: E402
from tests.simulated import cached_drive  # noqa: E402


def send(channel: str, record_dir: Path, sent_file: Path) -> None:
    messages = cached_drive("constant_radius", 41, 15.1).messages
    while not any(record_dir.glob("20*")):
        time.sleep(0.01)
    with can.Bus(interface="virtual", channel=channel) as bus, sent_file.open("wb", buffering=0) as sent:
        for i, message in enumerate(messages):
            bus.send(message)
            sent.write(f"{i} {time.monotonic():.6f}\n".encode())
            if i % 4 == 3:
                time.sleep(0.002)


if __name__ == "__main__":
    channel, record_dir, sent_file, raw_format = sys.argv[1:5]
    threading.Thread(target=send, args=(channel, Path(record_dir), Path(sent_file)), daemon=True).start()
    sys.exit(
        main(["live", "-i", "virtual", "-c", channel, "--record", record_dir, "--raw-format", raw_format])
    )
