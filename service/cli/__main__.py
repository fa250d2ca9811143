"""``python -m service.cli ARGS``: the ``railtwin`` command."""

from service.cli.main import run

run()
