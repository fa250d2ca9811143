"""``python -m service.cli ARGS``: the ``railtwin`` command."""

import sys

from service.cli.main import main

sys.exit(main())
