"""``python -m granpack``: the ``granpack`` command."""

from granpack.cli import main

if __name__ == "__main__":
    main()
