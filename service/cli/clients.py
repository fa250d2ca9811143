"""``railtwin feed``, ``railtwin feed-measured`` and ``railtwin synthesize``: the clients
(``service.clients``) as subcommands. Each client module has ``add_arguments(parser)`` and
``run(args) -> exit code`` (and a ``main`` for ``python -m``)."""

from __future__ import annotations

import argparse
from types import ModuleType

from service.cli.common import SubParsers
from service.clients import feeder, measured_feeder, synthesize


def _register(
    subparsers: SubParsers, name: str, summary: str, module: ModuleType
) -> argparse.ArgumentParser:
    description = module.__doc__.split("\n")[0] if module.__doc__ else summary
    p: argparse.ArgumentParser = subparsers.add_parser(name, help=summary, description=description)
    module.add_arguments(p)
    p.set_defaults(func=module.run)
    return p


def register_feed(subparsers: SubParsers) -> argparse.ArgumentParser:
    return _register(
        subparsers,
        "feed",
        "stream a train's wheel passages to a running twin, print the results",
        feeder,
    )


def register_feed_measured(subparsers: SubParsers) -> argparse.ArgumentParser:
    return _register(
        subparsers,
        "feed-measured",
        "publish measured forces of some wheels, print the diagnoses",
        measured_feeder,
    )


def register_synthesize(subparsers: SubParsers) -> argparse.ArgumentParser:
    return _register(
        subparsers,
        "synthesize",
        "write a synthetic measured force of one passage (CSV)",
        synthesize,
    )
