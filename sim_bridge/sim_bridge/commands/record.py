"""
Close a recording cut short: ``./lab record recover BAG``.

A bag whose recording ended without closing (a crash, ``kill -9``) keeps its ``metadata.yaml``
(written when the recording began) and the MCAP chunks that reached its file; ``recover``
rewrites those messages as a closed bag with its counts (sim_bridge.runner.record.recover).
"""

import argparse
from pathlib import Path
import sys

from sim_bridge.runner.record import recover
import yaml


def main(argv: list[str] | None = None) -> int:
    """``./lab record recover BAG``: close a bag that was cut short."""
    parser = argparse.ArgumentParser(prog='./lab record')
    commands = parser.add_subparsers(dest='command', required=True)
    recover_command = commands.add_parser('recover',
                                          help='close a bag whose recording was cut short')
    recover_command.add_argument('bag', type=Path)
    options = parser.parse_args(argv)
    try:
        counts = recover(options.bag)
    except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError) as error:
        print(f'cannot recover {options.bag}: {error}', file=sys.stderr)
        return 1
    print(f'{options.bag}: ' + ', '.join(f'{topic} {count}' for topic, count in counts.items()))
    return 0


if __name__ == '__main__':
    sys.exit(main())
