"""
The README's main job (``./dev.sh main``).

Until the ROS node exists this reproduces the paper. Later capabilities
replace it with the paper-validation scenario run against the node.
"""

import sys

from gyro_emulator import cli


def main(argv=None):
    """Run the main job; extra arguments are passed to the subcommand."""
    argv = list(sys.argv[1:] if argv is None else argv)
    return cli.main(['paper', '--json', 'out/paper/paper.json'] + argv)


if __name__ == '__main__':
    sys.exit(main())
