"""`python -m relit ...` runs the relit command line (the same code as the `relit` program)."""
import sys

from ._core import cli_main


def main(argv=None):
    argv = sys.argv[1:] if argv is None else list(argv)
    sys.stdout.flush()
    return cli_main(["relit"] + argv)


if __name__ == "__main__":
    sys.exit(main())


def _entry():
    """Console-script entry point of the `relit` command installed by pip."""
    sys.exit(main())
