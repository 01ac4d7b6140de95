"""The Ray driver: ``lightgrid bake --plan`` gives the task graph, every task becomes a
Ray task that runs ``lightgrid bake ... --task ID`` (its dependencies' outputs in the
store, its own written there under the hash of its inputs), and when all are done the
driver writes the manifest and the volumes into the output folder.

The Rust side knows nothing of Python or Ray: a task is a process, its inputs and
outputs are files in the store (a folder every worker reaches: local for ``--local``,
shared storage on a cluster). A task already in the store is not run again, so a
retried or repeated task writes nothing new and a re-bake after a change runs only the
tasks whose inputs changed.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from typing import Any, Dict, List, Optional

#: Environment variables forwarded to every task (``LIGHTGRID_*``: logging quiet, memory
#: limit, the fault hook of the tests).
FORWARD_PREFIX = "LIGHTGRID_"


def find_lightgrid(explicit: Optional[str] = None) -> str:
    """The ``lightgrid`` command: ``explicit``, ``$LIGHTGRID_BIN`` or the one on PATH."""
    for c in (explicit, os.environ.get("LIGHTGRID_BIN"), shutil.which("lightgrid")):
        if c:
            return os.path.abspath(c) if os.path.exists(c) else c
    raise FileNotFoundError(
        "no lightgrid command: install it (cargo install --path crates/cli), "
        "put it on PATH or pass --lightgrid / set LIGHTGRID_BIN"
    )


def load_plan(
    lightgrid: str,
    world: str,
    output: str,
    store: Optional[str] = None,
    depths: Optional[int] = None,
    extra: Optional[List[str]] = None,
) -> Dict[str, Any]:
    """Runs ``lightgrid bake world --plan`` and returns the plan (see the README)."""
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "plan.json")
        argv = [lightgrid, "bake", world, "--output", output, "--plan", path]
        if store:
            argv += ["--store", store]
        if depths is not None:
            argv += ["--depths", str(depths)]
        argv += extra or []
        r = subprocess.run(argv, capture_output=True, text=True)
        if r.returncode != 0:
            raise RuntimeError(f"planning failed ({r.returncode}): {r.stderr.strip()[-2000:]}")
        with open(path, encoding="utf-8") as f:
            return json.load(f)


def run_task(lightgrid: str, argv: List[str], env: Dict[str, str], *deps: Any) -> Dict[str, Any]:
    """One task, in this process's worker: runs the command and returns its outcome
    (``{"task", "hash", "ran", "seconds"}``). ``deps`` are the outcomes of the tasks it
    reads (Ray passes them once they are done; the data itself is in the store).

    A command killed by a signal takes its worker with it (``os._exit``), as a machine
    lost in the middle of a task would: Ray then runs the task again elsewhere
    (``max_retries``). A command that fails raises (retried with ``retry_exceptions``)."""
    del deps
    full_env = dict(os.environ)
    full_env.update(env)
    r = subprocess.run([lightgrid] + argv, capture_output=True, text=True, env=full_env)
    if r.returncode < 0:
        sys.stderr.write(f"lightgrid_ray: {argv[-1]} killed by signal {-r.returncode}\n")
        sys.stderr.flush()
        os._exit(1)
    if r.returncode != 0:
        raise RuntimeError(f"task {argv[-1]} failed ({r.returncode}): {r.stderr.strip()[-2000:]}")
    lines = [l for l in r.stdout.splitlines() if l.startswith("{")]
    return json.loads(lines[-1])


class _Bar:
    """A progress bar on stderr (one line, redrawn)."""

    def __init__(self, total: int, enabled: bool):
        self.total, self.done, self.enabled, self.t0 = total, 0, enabled, time.time()

    def step(self, what: str) -> None:
        self.done += 1
        if not self.enabled:
            return
        width = 30
        fill = width * self.done // max(self.total, 1)
        sys.stderr.write(
            f"\r[{'#' * fill}{'.' * (width - fill)}] {self.done}/{self.total} tasks "
            f"{time.time() - self.t0:6.1f} s  {what:<24}"
        )
        if self.done == self.total:
            sys.stderr.write("\n")
        sys.stderr.flush()


def bake(
    world: str,
    output: str,
    store: Optional[str] = None,
    lightgrid: Optional[str] = None,
    address: Optional[str] = None,
    local: bool = False,
    num_cpus: Optional[int] = None,
    depths: Optional[int] = None,
    max_retries: int = 3,
    progress: bool = True,
    extra: Optional[List[str]] = None,
) -> Dict[str, Any]:
    """Bakes ``world`` (a scene file) into ``output`` on Ray and returns a summary:
    ``tasks``, ``ran`` (tasks computed), ``reused`` (found in the store), ``seconds``
    and ``outcomes`` (one per task, in the plan's order).

    Ray is started here unless it already is: on the cluster at ``address``
    (``"auto"``: the one this machine belongs to), or with ``local=True`` a Ray of
    ``num_cpus`` on this machine. ``extra``: more ``lightgrid bake`` options (``--name``,
    ``--format``, ``--unit-scale``)."""
    import ray

    t0 = time.time()
    lg = find_lightgrid(lightgrid)
    plan = load_plan(lg, os.path.abspath(world), os.path.abspath(output), store and os.path.abspath(store), depths, extra)
    if not ray.is_initialized():
        if local:
            ray.init(num_cpus=num_cpus, include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=address, log_to_driver=False)
    env = {k: v for k, v in os.environ.items() if k.startswith(FORWARD_PREFIX)}
    # The task function travels by value: workers need Ray and the lightgrid command,
    # not this package.
    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])
    remote = ray.remote(run_task)
    refs: Dict[str, Any] = {}
    manifest = None
    for t in plan["tasks"]:
        if t["kind"] == "manifest":
            manifest = t
            continue
        deps = [refs[d] for d in t["deps"]]
        refs[t["id"]] = remote.options(
            name=t["id"],
            num_cpus=1,
            memory=int(t["memory_bytes"]),
            max_retries=max_retries,
            retry_exceptions=True,
        ).remote(lg, t["argv"], env, *deps)
    bar = _Bar(len(plan["tasks"]), progress)
    pending = list(refs.values())
    outcomes: Dict[str, Dict[str, Any]] = {}
    while pending:
        ready, pending = ray.wait(pending, num_returns=1)
        o = ray.get(ready[0])
        outcomes[o["task"]] = o
        bar.step(o["task"])
    if manifest is not None:
        # Every volume is in the store: the manifest and the output folder, here.
        o = run_task(lg, manifest["argv"], env)
        outcomes[o["task"]] = o
        bar.step(o["task"])
    ordered = [outcomes[t["id"]] for t in plan["tasks"]]
    ran = sum(1 for o in ordered if o["ran"])
    return {
        "tasks": len(ordered),
        "ran": ran,
        "reused": len(ordered) - ran,
        "seconds": time.time() - t0,
        "outcomes": ordered,
    }


def main(argv: Optional[List[str]] = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m lightgrid_ray",
        description="Bake a lightgrid world on Ray: every task of `lightgrid bake --plan` as a Ray task.",
    )
    sub = p.add_subparsers(dest="command", required=True)
    b = sub.add_parser("bake", help="bake a world (a scene file) into Bevy volumes and a manifest")
    b.add_argument("world", help="the scene file (.toml)")
    b.add_argument("-o", "--output", required=True, help="output folder")
    b.add_argument("--store", help="the store, a folder every worker reaches (default <output>/.lightgrid-store)")
    b.add_argument("--address", default=None, help='Ray cluster address ("auto": the one this machine is in)')
    b.add_argument("--local", action="store_true", help="start a Ray on this machine")
    b.add_argument("--num-cpus", type=int, default=None, help="CPUs of the local Ray")
    b.add_argument("--lightgrid", default=None, help="the lightgrid command (default $LIGHTGRID_BIN or PATH)")
    b.add_argument("--depths", type=int, default=None, help="node depths to bake (default all)")
    b.add_argument("--max-retries", type=int, default=3, help="retries of a failed task")
    b.add_argument("--name", default=None, help="file stem of the volumes (default volume)")
    b.add_argument("--format", default=None, choices=["rgb9e5", "rg11b10"], help="texel format")
    b.add_argument("--unit-scale", default=None, help="factor to Bevy's units (see lightgrid bake --help)")
    b.add_argument("--json", action="store_true", help="print the summary as JSON")
    a = p.parse_args(argv)
    if not a.local and a.address is None:
        p.error("give --address (a cluster, or auto) or --local")
    s = bake(
        a.world,
        a.output,
        store=a.store,
        lightgrid=a.lightgrid,
        address=a.address,
        local=a.local,
        num_cpus=a.num_cpus,
        depths=a.depths,
        max_retries=a.max_retries,
        extra=[
            x
            for k, v in (("--name", a.name), ("--format", a.format), ("--unit-scale", a.unit_scale))
            if v is not None
            for x in (k, str(v))
        ],
    )
    if a.json:
        print(json.dumps(s, indent=2))
    else:
        print(
            f"baked {s['tasks']} tasks in {s['seconds']:.1f} s: {s['ran']} ran, "
            f"{s['reused']} found in the store -> {a.output}"
        )
    return 0
