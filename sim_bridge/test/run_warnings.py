"""A run's own warnings: without the one every run has on a machine that is not fully sandboxed."""

from sim_bridge.runner.boundary.outside.node_sandbox import isolation_warning


def run_warnings(metrics: dict) -> list[str]:
    """
    Return ``metrics``' warnings but the sandbox's (``runs PARTLY|NOT sandboxed: ...``).

    That one says what the machine allows (as root without bubblewrap, as an ordinary user
    without it), the same for every run there: tests of a run's own warnings leave it out.
    """
    machine = isolation_warning(metrics.get('run_mode', {}).get('sandbox', ''))
    return [warning for warning in metrics['warnings'] if warning != machine]
