"""Worker processes that end with the command that made them, however it ends."""

import multiprocessing
import os
import threading


def ends_with_parent() -> None:
    """A process pool's initializer: the worker ends when the process that made it is gone. A
    kill -9 of `c2n simulate --campaign` left its worker blocked on its task pipe for good (190 MB),
    and a fork server's children are not the command's at all."""
    parent = multiprocessing.parent_process()
    if parent is not None:
        threading.Thread(target=_end_with, args=(parent,), name="c2n-parent", daemon=True).start()


def _end_with(parent: multiprocessing.process.BaseProcess) -> None:
    parent.join()  # its sentinel: returns when the parent has gone
    os._exit(1)
