"""Bakes lightgrid worlds on Ray: the task graph of ``lightgrid bake --plan`` run as Ray
tasks, each one a ``lightgrid bake ... --task ID`` process reading and writing a shared
store. See ``README.md``."""

from .driver import bake, load_plan

__all__ = ["bake", "load_plan"]
