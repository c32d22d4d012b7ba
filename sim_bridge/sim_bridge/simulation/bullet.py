"""
pybullet, imported without the line its C module writes to stderr as it loads.

pybullet writes "pybullet build time: ..." to stderr when a process imports it: every command
of the kit would print it before anything of its own. The kit's modules import pybullet from
here (``from sim_bridge.simulation.bullet import pybullet``), so that its first import in a
process sends that one write nowhere; what pybullet writes later reaches stderr as usual.
"""

import os
import sys


def _import_quietly():
    """Import pybullet with stderr's file descriptor on /dev/null; return the module."""
    sys.stderr.flush()
    try:
        saved = os.dup(2)
    except OSError:  # no stderr to keep quiet
        import pybullet
        return pybullet
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        import pybullet
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)
    return pybullet


pybullet = _import_quietly()
