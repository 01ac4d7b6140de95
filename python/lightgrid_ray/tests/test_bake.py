"""The Ray driver against the single-process bake, on a local Ray of 2 CPUs.

Run from the repository root after `cargo build -p lightgrid`:
``python -m unittest discover -s python/lightgrid_ray/tests -v``
(``LIGHTGRID_BIN`` names another build of the command).
"""

import json
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "python", "lightgrid_ray"))

import ray  # noqa: E402

import lightgrid_ray  # noqa: E402
from lightgrid_ray.driver import find_lightgrid, load_plan  # noqa: E402

WORLD = os.path.join(ROOT, "crates", "cli", "tests", "data", "world.toml")
LIGHTGRID = os.environ.get("LIGHTGRID_BIN") or os.path.join(ROOT, "target", "debug", "lightgrid")


def files(folder):
    """Every file under `folder` (relative name -> bytes), the store left out."""
    out = {}
    for d, dirs, names in os.walk(folder):
        dirs[:] = [x for x in dirs if x != ".lightgrid-store"]
        for n in names:
            p = os.path.join(d, n)
            with open(p, "rb") as f:
                out[os.path.relpath(p, folder)] = f.read()
    return out


class RayBake(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        if not os.path.exists(LIGHTGRID):
            raise RuntimeError(f"{LIGHTGRID} missing: run `cargo build -p lightgrid` first")
        os.environ["LIGHTGRID_QUIET"] = "1"
        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
        cls.tmp = tempfile.mkdtemp(prefix="lightgrid-ray-")
        # The single-process bake, the reference every Ray bake must equal.
        cls.single = os.path.join(cls.tmp, "single")
        r = subprocess.run(
            [LIGHTGRID, "bake", WORLD, "-o", cls.single, "--store", os.path.join(cls.tmp, "single-store")],
            capture_output=True,
            text=True,
        )
        if r.returncode != 0:
            raise RuntimeError(r.stderr)
        cls.reference = files(cls.single)

    @classmethod
    def tearDownClass(cls):
        ray.shutdown()
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def bake(self, name, world=WORLD, store=None, **kw):
        out = os.path.join(self.tmp, name)
        store = store or os.path.join(self.tmp, name + "-store")
        s = lightgrid_ray.bake(world, out, store=store, lightgrid=LIGHTGRID, progress=False, **kw)
        return out, store, s

    def test_ray_bake_equals_the_single_process_bake(self):
        out, _, s = self.bake("ray")
        got = files(out)
        self.assertEqual(sorted(got), sorted(self.reference))
        self.assertGreater(len(got), 10)
        for name, data in self.reference.items():
            self.assertEqual(got[name], data, name)
        self.assertEqual(s["ran"], s["tasks"])
        manifest = json.loads(got["volume.manifest.json"])
        self.assertEqual(len(manifest["volumes"]) * 3 + 1, len(got))

    def test_a_task_killed_half_way_is_retried_and_leaves_no_partial_files(self):
        marker = os.path.join(self.tmp, "fault-marker")
        os.environ["LIGHTGRID_BAKE_FAULT"] = "node-2-1-1@" + marker
        try:
            out, store, s = self.bake("fault")
        finally:
            del os.environ["LIGHTGRID_BAKE_FAULT"]
        self.assertTrue(os.path.exists(marker), "the fault was never injected")
        got = files(out)
        self.assertEqual(sorted(got), sorted(self.reference))
        for name, data in self.reference.items():
            self.assertEqual(got[name], data, name)
        objects = os.listdir(os.path.join(store, "objects"))
        self.assertEqual([o for o in objects if o.startswith(".tmp")], [], "partial outputs left")
        # One folder per task with an output in the store (all but the manifest).
        self.assertEqual(len(objects), s["tasks"] - 1)

    def test_a_rebake_runs_only_the_tasks_whose_inputs_changed(self):
        store = os.path.join(self.tmp, "incremental-store")
        _, _, first = self.bake("incremental", store=store)
        self.assertEqual(first["ran"], first["tasks"])
        # The same world again: nothing but the manifest runs.
        _, _, again = self.bake("incremental-again", store=store)
        self.assertEqual(again["ran"], 1)
        # One instance moved: every task whose input hash changed runs, no other.
        with open(WORLD, encoding="utf-8") as f:
            text = f.read()
        moved = text.replace("position = [20.0, 18.0]", "position = [21.0, 18.0]")
        self.assertNotEqual(moved, text)
        world2 = os.path.join(self.tmp, "world-moved.toml")
        with open(world2, "w", encoding="utf-8") as f:
            f.write(moved)
        lg = find_lightgrid(LIGHTGRID)
        old = {t["id"]: t["hash"] for t in load_plan(lg, WORLD, os.path.join(self.tmp, "x"), store)["tasks"]}
        new = {t["id"]: t["hash"] for t in load_plan(lg, world2, os.path.join(self.tmp, "x"), store)["tasks"]}
        changed = {i for i in new if new[i] != old.get(i)} - {"manifest"}
        _, _, moved_bake = self.bake("incremental-moved", world=world2, store=store)
        ran = {o["task"] for o in moved_bake["outcomes"] if o["ran"]} - {"manifest"}
        self.assertEqual(ran, changed)
        # Export settings changed: the volumes are written again, no grid is swept.
        _, _, scaled = self.bake("incremental-scaled", world=world2, store=store, extra=["--unit-scale", "2"])
        ran = {o["task"] for o in scaled["outcomes"] if o["ran"]} - {"manifest"}
        self.assertEqual(len(ran), sum(1 for o in scaled["outcomes"] if o["task"].startswith("export-")))
        self.assertTrue(all(r.startswith("export-") for r in ran), ran)


if __name__ == "__main__":
    unittest.main()
