"""``python -m sensact`` is the ``sensact`` command."""

from sensact.cli import main

main()
