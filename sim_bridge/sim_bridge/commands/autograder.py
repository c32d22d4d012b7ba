"""
``./lab autograder SCENARIO... [-o autograder.zip]``: build Gradescope's autograder.zip.

``./lab autograder SCENARIO... -o autograder.zip`` packs the kit,
the chosen scenario files, ``setup.sh`` and ``run_autograder`` (what each holds and does:
sim_bridge.grading.gradescope, and docs/instructors.md, Gradescope).
"""

import argparse
from pathlib import Path
import sys

from sim_bridge.common.paths import repo_root
from sim_bridge.grading.gradescope import build, SCENARIOS_DIR


def main(argv: list[str] | None = None) -> int:
    """Build autograder.zip (the ``build`` command); return 0, or 2 with a one-line error."""
    parser = argparse.ArgumentParser(
        prog='./lab autograder',
        description="Build Gradescope's autograder.zip: the kit, the scenarios, setup.sh and "
        'run_autograder.')
    commands = parser.add_subparsers(dest='command', required=True)
    command = commands.add_parser('build', help='build autograder.zip')
    command.add_argument('scenarios', nargs='+', metavar='SCENARIO',
                         help='the scenario files (or folders of them) to grade with')
    command.add_argument('-o', '--output', type=Path, default=Path('autograder.zip'),
                         metavar='ZIP', help='the zip to write (default autograder.zip)')
    args = parser.parse_args(argv)
    root = repo_root()
    try:
        if root is None:
            raise ValueError('the kit is not a source checkout (no worlds/ and models/ beside '
                             'its packages): build the autograder from the workspace')
        names = build(args.scenarios, args.output, root)
    except (ValueError, OSError) as error:
        print(f'error: {error}', file=sys.stderr)
        return 2
    scenarios = [name for name in names if name.startswith(f'{SCENARIOS_DIR}/')]
    print(f'{args.output}: {len(names)} files, {args.output.stat().st_size / 2 ** 20:.1f} MiB; '
          f'{len(scenarios)} scenarios: '
          + ', '.join(Path(name).stem for name in scenarios)
          + '. Upload it on the assignment\'s "Configure Autograder" page.')
    return 0


if __name__ == '__main__':
    sys.exit(main())
