"""Imported by the campaign's fork server alone (``work.PRELOAD``), for its one effect: the server
leaves SIGTERM and SIGHUP — sent to the whole process group by systemd's stop, a scheduler's
cancel or `kill -- -PGID` — to the campaign, as it leaves Ctrl-C. Killed by one, it took with it
the pipes by which the pool sees its workers alive: the pool took every worker for dead, and
Python 3.11's then waited for good, the output folder claimed. It ends with the campaign anyway
(its pipe from the campaign closes), and the workers it forks ignore them too
(``work._start_worker``)."""

import signal

for _ending in (signal.SIGTERM, signal.SIGHUP):
    signal.signal(_ending, signal.SIG_IGN)
