"""
What a graded run may use, and the job it runs: the limits (time, stall, memory) and the run.

The defaults are the grader's command line's (sim_bridge.commands.grade);
sim_bridge.grading.isolate enforces them. The memory limit is what a run's nodes may use
(the sandbox's memory of their process tree,
:func:`sim_bridge.runner.boundary.outside.node_sandbox.node_limits`); each process of the run may
reserve ADDRESS_SPACE_SLACK_BYTES of address space beyond it, as an rclpy process does (thread
stacks, arenas), the run's own (the simulator) included.
"""

from dataclasses import dataclass, field
from pathlib import Path
import resource
from typing import Any

from sim_bridge.grading.scenario import ScenarioRun
from sim_bridge.runner.boundary.outside.node_sandbox import LEAST_MEMORY_BYTES
from sim_bridge.runner.boundary.outside.sandbox import ADDRESS_SPACE_SLACK_BYTES


#: Wall seconds a run may take: BUDGET_BASE_S (start-up, writing outputs) plus this many per
#: simulated second (a stepped run slower than real time is a node doing far too much per
#: callback).
BUDGET_BASE_S = 60.0
BUDGET_PER_SIM_S = 1.0
#: Wall seconds without a simulated second passing before the run is stopped.
DEFAULT_STALL_S = 30.0
#: Wall seconds a child may take to start (rclpy, pybullet, the nodes' constructors) before
#: simulated time starts, if the stall limit is shorter.
DEFAULT_STARTUP_S = 30.0
DEFAULT_MEMORY_BYTES = 2 * 2 ** 30
#: The largest address space setrlimit takes (bytes) where the hard limit is unlimited.
MAX_ADDRESS_SPACE_BYTES = 2 ** 63 - 1


@dataclass(frozen=True)
class Limits:
    """
    What a child run may use, in wall-clock time and memory.

    ``timeout_s`` (s) is the run's wall-clock budget (None: derived from its duration),
    ``stall_s`` (s) the wall time without simulated progress it may take, ``startup_s`` (s)
    what it may take to start if that is longer, ``memory_bytes`` (bytes) the memory of its
    nodes (see the module docstring).
    """

    timeout_s: float | None = None
    stall_s: float = DEFAULT_STALL_S
    memory_bytes: int = DEFAULT_MEMORY_BYTES
    startup_s: float = DEFAULT_STARTUP_S

    @property
    def address_space_bytes(self) -> int:
        """Return the address space (bytes) of a run's processes: its memory and the reserve."""
        return self.memory_bytes + ADDRESS_SPACE_SLACK_BYTES

    def stall_limit_s(self, started: bool) -> float:
        """Return the wall seconds (s) a run may go without progress, before or once started."""
        return self.stall_s if started else max(self.stall_s, self.startup_s)

    def budget_s(self, duration_s: float) -> float:
        """Return the wall-clock budget (s) of a run of ``duration_s`` simulated seconds."""
        if self.timeout_s is not None:
            return self.timeout_s
        return BUDGET_BASE_S + BUDGET_PER_SIM_S * duration_s


def check_memory_limit(memory_bytes: int, shown: str) -> None:
    """
    Raise ValueError for a memory limit (bytes) a run cannot work in or the machine cannot set.

    The one line names ``shown`` (the option as given). Below LEAST_MEMORY_BYTES no rclpy
    node starts; above this process's hard address-space limit, less the reserve each process
    of a run gets, the limit cannot be set.
    """
    if memory_bytes < LEAST_MEMORY_BYTES:
        raise ValueError(f'{shown} is less than the {LEAST_MEMORY_BYTES / 2 ** 30:g} GiB '
                         f'({LEAST_MEMORY_BYTES / 2 ** 20:g} MiB) an rclpy node needs to run')
    _, hard = resource.getrlimit(resource.RLIMIT_AS)
    highest = (MAX_ADDRESS_SPACE_BYTES if hard == resource.RLIM_INFINITY else hard) \
        - ADDRESS_SPACE_SLACK_BYTES
    if memory_bytes > highest:
        raise ValueError(f'{shown} is more than this machine can set as a limit '
                         f'({max(highest, 0) / 2 ** 30:g} GiB: its address space less the '
                         f'{ADDRESS_SPACE_SLACK_BYTES / 2 ** 30:g} GiB each process reserves)')


@dataclass(frozen=True)
class Job:
    """A run for a child: the scenario run, its output folder, its limits and runner options."""

    run: ScenarioRun
    out_dir: Path
    limits: Limits
    options: dict[str, Any] = field(default_factory=dict)

    @property
    def budget_s(self) -> float:
        """Return the run's wall-clock budget (s): its limits' for its duration."""
        return self.limits.budget_s(self.run.scenario.duration_s)
