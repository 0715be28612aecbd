"""``python -m dse_runner``: the ``dse-runner`` command."""

from .interfaces.cli import main

main()
