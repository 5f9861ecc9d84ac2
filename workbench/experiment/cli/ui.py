"""``workbench ui``: the MLflow UI and optuna-dashboard on 127.0.0.1, until Ctrl-C.

The MLflow UI serves the tracking store and, beside it, optuna-dashboard the sweeps'
studies.
"""

from __future__ import annotations

import argparse
import logging
import subprocess
import time
from pathlib import Path

from ..process.errors import redact

__all__ = ["run"]

log = logging.getLogger("workbench")


def _commands(args: argparse.Namespace) -> list[list[str]]:
    """Return the servers' command lines, their addresses printed.

    The stores are checked first, as every command checks them (a server would print a
    traceback, or sit on a store it cannot read).
    """
    from ..tracking.uris import check_store_uri, resolve_tracking_uri
    from ..tracking.views import experiment_views, ui_command, ui_url

    uri = resolve_tracking_uri(args.tracking_uri, None, Path.cwd())
    check_store_uri(uri)
    storage = args.storage or "mlruns/optuna.journal"
    serve_studies = args.storage is not None or (Path.cwd() / storage).is_file()
    if serve_studies:
        from ..storage import check_storage

        check_storage(storage, Path.cwd())
    cmds = [ui_command(uri, args.port, args.workers)]
    print(f"MLflow UI for {redact(uri)} at {ui_url(args.port)}", flush=True)
    for name, url in experiment_views(uri, args.port):
        print(f"  {name}: {url}", flush=True)
    print("  (a run's own page opens in MLflow's GenAI view until the sidebar's \"Model "
          "training\" switch is clicked once; the browser remembers it)", flush=True)
    if serve_studies:  # the studies beside the runs
        from ..storage import dashboard_command

        cmds.append(dashboard_command(storage, args.dashboard_port, Path.cwd()))
        print(f"Optuna dashboard for {redact(storage)} at "
              f"http://127.0.0.1:{args.dashboard_port}", flush=True)
    return cmds


def run(args: argparse.Namespace) -> int:
    """``workbench ui``: start the servers and wait for Ctrl-C or a server's end.

    Parameters
    ----------
    args : argparse.Namespace
        The command's arguments.

    Returns
    -------
    int
        0 after Ctrl-C, else the largest exit code of the servers.
    """
    cmds = _commands(args)
    print("Ctrl-C stops", "them" if len(cmds) > 1 else "it", flush=True)
    from ..tracking.views import ui_env

    procs = [subprocess.Popen(cmd, env=ui_env()) for cmd in cmds]
    try:
        while all(p.poll() is None for p in procs):
            time.sleep(0.5)
        return max(p.returncode or 0 for p in procs)
    except KeyboardInterrupt:
        return 0
    finally:
        for p in procs:
            if p.poll() is None:
                p.terminate()
        for p in procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
