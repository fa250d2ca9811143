"""The ``railtwin`` command line.

    railtwin simulate SCENARIO.json --out RESULT.json   # one case in, one result out
    railtwin simulate A.json B.json ... --out-dir DIR   # batch: DIR/A.json, DIR/B.json, ...
    railtwin schema [NAME]                              # JSON Schemas of the contract
    railtwin figures --out DIR                          # the paper's figures

One module a subcommand (or a group): it exposes ``register(subparsers)`` that adds its
parser and sets ``func`` (``handler(args) -> exit code``) with ``set_defaults``. The
built-in commands are registered below, the service's in ``SERVICE_COMMANDS``.
``register`` must stay cheap: heavy libraries (numba, rerun, matplotlib) are imported inside
the handler, not at module level, so that ``railtwin --help`` starts fast.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import os
import sys
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import IO, Any, NoReturn, cast

from service.cli.common import (
    EXIT_CODES_HELP,
    EXIT_FAILURE,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_USAGE,
    CommandError,
    SubParsers,
    one_line,
    read_json,
    write_atomic,
)

PROG = "railtwin"


class _Parser(argparse.ArgumentParser):
    """argparse with the usual Unix behaviour: usage errors exit 2 with one clear line."""

    def error(self, message: str) -> NoReturn:
        self.print_usage(sys.stderr)
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n")


# --- simulate -------------------------------------------------------------------------------

BATCH_EXIT_CODES_HELP = """\
batch mode (several scenarios, --out-dir DIR):
  Every file is attempted in order, in one process (the compiled physics is
  loaded once, before the first scenario, so each result's stats.wall_time is
  that scenario's own time). A file that fails gets one line on stderr and is
  skipped; the others are still written. The exit status comes at the end:
  2 if any file was unreadable or invalid, else 1 if any simulation or write
  failed, else 0.
"""


def register_simulate(subparsers: SubParsers) -> None:
    p = subparsers.add_parser(
        "simulate",
        help="run scenario files and write their results",
        description=(
            "Validate SCENARIO (CONTRACT.md), simulate every pass and write the "
            "result JSON. Prints a summary table on stdout (or JSON with --format "
            "json); progress of multi-pass runs goes to stderr. Invalid scenarios are "
            "reported on stderr with the offending field's path, and exit 2. "
            "With several scenarios (batch mode) give --out-dir DIR: the result of "
            "A.json is written to DIR/A.json, progress goes to stderr."
        ),
        epilog=EXIT_CODES_HELP + "\n" + BATCH_EXIT_CODES_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "scenario",
        metavar="SCENARIO.json",
        nargs="+",
        help="scenario file ('-' for stdin; several need --out-dir)",
    )
    out = p.add_mutually_exclusive_group()
    out.add_argument(
        "-o",
        "--out",
        metavar="RESULT.json",
        help="write the result here ('-' for stdout, which replaces the summary)",
    )
    out.add_argument(
        "--out-dir",
        metavar="DIR",
        help="batch mode: write each result to DIR/<scenario file name> (.json)",
    )
    p.add_argument(
        "--format",
        choices=("table", "json"),
        default="table",
        help="summary on stdout and errors on stderr as a table/text (default) or JSON",
    )
    p.add_argument("-q", "--quiet", action="store_true", help="no summary, no progress")
    p.set_defaults(func=cmd_simulate)


def cmd_simulate(args: argparse.Namespace) -> int:
    if args.out_dir is not None:
        return _simulate_batch(args)
    if len(args.scenario) > 1:
        raise CommandError(
            f"{len(args.scenario)} scenarios need --out-dir DIR (one result file each)",
            EXIT_USAGE,
        )
    path = args.scenario[0]
    source = "<stdin>" if path == "-" else path
    scenario = _load_scenario(path, source)
    result = _run(scenario, source, args)
    text = result.model_dump_json()
    if args.out == "-":
        sys.stdout.write(text + "\n")
        return EXIT_OK
    if args.out:
        write_atomic(Path(args.out), text)
    if not args.quiet:
        if args.format == "json":
            sys.stdout.write(json.dumps(summary_document(result, args.out)) + "\n")
        else:
            sys.stdout.write(summary_table(result, source, args.out))
    return EXIT_OK


def _load_scenario(path: str, source: str) -> Any:
    """The validated ``Scenario`` of ``path``; CommandError (exit 2) if unreadable or invalid."""
    from pydantic import ValidationError

    from schemas.errors import ErrorReport
    from schemas.scenario import Scenario

    data = read_json(path, source)
    try:
        return Scenario.model_validate(data)
    except ValidationError as exc:
        report = ErrorReport.from_validation_error(exc, data, source)
        raise CommandError(f"invalid scenario {report.to_text()}", EXIT_USAGE, report) from None


def _run(scenario: Any, source: str, args: argparse.Namespace) -> Any:
    """``run_scenario`` with pass progress on stderr; CommandError (exit 1) if it fails."""
    from schemas.errors import ErrorReport
    from service.physics.scenario_runner import run_scenario

    progress = None
    if scenario.passes > 1 and not args.quiet:
        progress = _ProgressPrinter(sys.stderr)
    from sim_core.track.spec import TrackError

    try:
        return run_scenario(scenario, progress=progress)
    except KeyboardInterrupt:
        raise
    except TrackError as exc:  # a track the physics cannot take (too many modes): the input's
        message = f"invalid scenario {source}: {exc}"
        raise CommandError(
            message,
            EXIT_USAGE,
            ErrorReport(error="invalid_scenario", message=message, source=source),
        ) from None
    except Exception as exc:
        if args.debug:
            traceback.print_exc()
        message = f"simulation failed: {type(exc).__name__}: {exc}"
        raise CommandError(
            message,
            EXIT_FAILURE,
            ErrorReport(error="runtime_error", message=message, source=source),
        ) from None
    finally:
        if progress is not None:
            progress.close()


def batch_outputs(paths: Sequence[str], out_dir: Path) -> list[Path]:
    """DIR/<file name, with the suffix .json> for each scenario path.

    Raises CommandError (exit 2) for stdin, for two inputs that would write the
    same file, and for an output that would overwrite its own input.
    """
    outs: list[Path] = []
    seen: dict[Path, str] = {}
    for path in paths:
        if path == "-":
            raise CommandError(
                "batch mode (--out-dir) needs scenario files: '-' (stdin) has no name", EXIT_USAGE
            )
        out = out_dir / Path(path).with_suffix(".json").name
        if out in seen:
            raise CommandError(f"{seen[out]} and {path} would both be written to {out}", EXIT_USAGE)
        seen[out] = path
        try:
            same = out.exists() and out.samefile(path)
        except OSError:
            same = False
        if same:
            raise CommandError(
                f"{out} would overwrite its own scenario {path}: choose another --out-dir",
                EXIT_USAGE,
            )
        outs.append(out)
    return outs


def _simulate_batch(args: argparse.Namespace) -> int:
    """``simulate A.json B.json ... --out-dir DIR``: one process, one result file each."""
    import time

    paths: list[str] = list(args.scenario)
    outs = batch_outputs(paths, Path(args.out_dir))
    n = len(paths)
    failures: list[int] = []
    warmed = False
    for i, (path, out) in enumerate(zip(paths, outs, strict=True), start=1):
        tag = f"[{i}/{n}] {path}"
        try:
            scenario = _load_scenario(path, path)
            if not warmed:
                warmed = True
                from service.physics.scenario_runner import warm_up

                seconds = warm_up()
                _note(args, f"compiled physics loaded in {seconds:.2f} s")
            started = time.perf_counter()
            result = _run(scenario, path, args)
            write_atomic(out, result.model_dump_json())
            elapsed = time.perf_counter() - started
        except CommandError as exc:
            failures.append(exc.code)
            _report_one_line(exc, args, f"[{i}/{n}]", path)
            continue
        wall = result.stats.wall_time if result.stats is not None else None
        _note(
            args,
            f"{tag} -> {out}"
            + (f": simulated in {wall:.3f} s" if wall is not None else "")
            + f", {elapsed:.3f} s with writing",
        )
        if not args.quiet:
            if args.format == "json":
                doc = summary_document(result, str(out))
                doc["source"] = path
                sys.stdout.write(json.dumps(doc) + "\n")
            else:
                sys.stdout.write(summary_table(result, path, str(out)) + "\n")
            sys.stdout.flush()
    done = n - len(failures)
    _note(args, f"{done} of {n} scenario{'s' if n != 1 else ''} written to {args.out_dir}")
    if EXIT_USAGE in failures:
        return EXIT_USAGE
    return EXIT_FAILURE if failures else EXIT_OK


def _note(args: argparse.Namespace, line: str) -> None:
    """A progress line of batch mode on stderr (silenced by --quiet)."""
    if not args.quiet:
        sys.stderr.write(f"{PROG} {args.command}: {line}\n")
        sys.stderr.flush()


def _report_one_line(exc: CommandError, args: argparse.Namespace, tag: str, source: str) -> None:
    """A failed scenario of a batch: one line on stderr (an ErrorReport line with --format json)."""
    if getattr(args, "format", "table") == "json" and exc.report is not None:
        sys.stderr.write(exc.report.model_dump_json() + "\n")
        return
    text = one_line(str(exc))
    if source not in text:
        text = f"{source}: {text}"
    sys.stderr.write(f"{PROG} {args.command}: {tag} {text}\n")
    sys.stderr.flush()


class _ProgressPrinter:
    """``progress(done, total)`` for stderr: a rewritten line on a terminal, lines otherwise."""

    def __init__(self, stream: IO[str]) -> None:
        self.stream = stream
        self.tty = stream.isatty()
        self.dirty = False

    def __call__(self, done: int, total: int) -> None:
        line = f"{PROG}: pass {done}/{total}"
        if self.tty:
            self.stream.write("\r" + line)
            self.dirty = True
        else:
            self.stream.write(line + "\n")
        self.stream.flush()

    def close(self) -> None:
        if self.dirty:
            self.stream.write("\n")
            self.stream.flush()
            self.dirty = False


def summary_document(result: Any, out: str | None) -> dict[str, Any]:
    """The machine-readable report of ``simulate --format json``."""
    doc: dict[str, Any] = result.model_dump(
        mode="json", include={"derived", "summary", "passes_summary", "stats"}
    )
    doc["transitions"] = len(result.transitions)
    doc["samples"] = len(result.series.t)
    doc["out"] = out
    return doc


def summary_table(result: Any, source: str, out: str | None) -> str:
    """A human summary: scenario line, derived constants, one row per pass."""
    s = result.scenario
    d = result.derived
    n = s.passes
    lines = [
        f"{source}: {s.contact} contact, {s.rail.kind} rail, {s.wheel.outline.kind} wheel, "
        f"{s.foundation.kind} foundation; {n} pass{'es' if n != 1 else ''} of "
        f"{s.duration:g} s at {s.speed:g} m/s",
        f"derived: C = {d.contact_coefficient:.5g} N/m^1.5, "
        f"δ0 = {d.static_indentation * 1e6:.1f} µm, f0 = {d.contact_frequency:.1f} Hz"
        + (
            f", F_Y = {d.yield_force / 1e3:.1f} kN, δ_Y = {d.yield_indentation * 1e6:.1f} µm"
            if d.yield_force is not None and d.yield_indentation is not None
            else ""
        ),
        "",
    ]
    header = (
        "pass",
        "peak F [kN]",
        "min F [kN]",
        "losses",
        "1st loss [s]",
        "out of contact",
        "max δ [µm]",
        "max dent [µm]",
    )
    rows: list[tuple[str, ...]] = [header]
    for i, p in enumerate(result.passes_summary, start=1):
        rows.append(
            (
                str(i),
                f"{p.peak_force / 1e3:.2f}",
                f"{p.min_force / 1e3:.2f}",
                str(p.contact_losses),
                "-" if p.first_loss_time is None else f"{p.first_loss_time:.6f}",
                f"{100.0 * p.time_out_of_contact / s.duration:.1f} %",
                f"{p.max_indentation * 1e6:.2f}",
                f"{p.max_dent * 1e6:.2f}",
            )
        )
    if len(rows) > 41:  # long multi-pass runs: first and last passes
        rows = [*rows[:21], tuple("⋮" if j == 0 else "" for j in range(len(header))), *rows[-20:]]
    widths = [max(len(r[j]) for r in rows) for j in range(len(header))]
    for r in rows:
        lines.append("  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)))
    lines.append("")
    tail = f"{len(result.series.t)} samples, {len(result.transitions)} transitions (last pass)"
    if result.stats is not None and result.stats.wall_time is not None:
        tail += f"; {result.stats.steps} steps in {result.stats.wall_time:.2f} s"
    lines.append(tail)
    lines.append(f"result written to {out}" if out else "result not written (no --out)")
    return "\n".join(lines) + "\n"


# --- schema ---------------------------------------------------------------------------------


def register_schema(subparsers: SubParsers) -> None:
    p = subparsers.add_parser(
        "schema",
        help="print the JSON Schemas of the contract",
        description=(
            "Print the JSON Schema of every top-level model as one JSON object "
            "{name: schema}, or of the model NAME alone; with --out DIR, write one file "
            "<Name>.schema.json per model there (as committed in schemas/json/)."
        ),
        epilog=EXIT_CODES_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("name", nargs="?", metavar="NAME", help="model name, e.g. Scenario, Result")
    p.add_argument("--indent", type=int, default=2, help="JSON indentation (default 2)")
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="DIR",
        help="write every model's schema into DIR (e.g. schemas/json) instead",
    )
    p.set_defaults(func=cmd_schema)


def cmd_schema(args: argparse.Namespace) -> int:
    from schemas import all_json_schemas, export

    if args.out is not None:
        if args.name is not None:
            raise CommandError("--out writes every schema: give no NAME with it", EXIT_USAGE)
        try:
            paths = export.write(args.out)
        except OSError as exc:
            raise CommandError(f"cannot write {args.out}: {exc.strerror or exc}") from None
        sys.stdout.write(f"wrote {len(paths)} JSON Schemas to {args.out}\n")
        return EXIT_OK

    schemas = all_json_schemas()
    doc: Any = schemas
    if args.name is not None:
        by_lower = {k.lower(): k for k in schemas}
        key = by_lower.get(args.name.lower())
        if key is None:
            raise CommandError(
                f"no schema named {args.name!r}; known: {', '.join(sorted(schemas))}", EXIT_USAGE
            )
        doc = schemas[key]
    sys.stdout.write(json.dumps(doc, indent=args.indent or None, ensure_ascii=False) + "\n")
    return EXIT_OK


# --- figures --------------------------------------------------------------------------------


def register_figures(subparsers: SubParsers) -> None:
    p = subparsers.add_parser(
        "figures",
        help="draw the paper's figures (needs matplotlib)",
        description="Draw the figures of MODEL.md §6 into DIR and list the files written.",
        epilog=EXIT_CODES_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--out", metavar="DIR", default="figures", help="output directory (default figures/)"
    )
    p.set_defaults(func=cmd_figures)


def cmd_figures(args: argparse.Namespace) -> int:
    try:
        import matplotlib

        matplotlib.use("Agg")
    except ModuleNotFoundError:
        raise CommandError(
            "matplotlib is not installed: pip install -e '.[figures]' (or make figures)"
        ) from None
    from service.cli import figures

    out = Path(args.out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CommandError(f"cannot create {out}: {exc.strerror or exc}") from None
    paths = figures.make_figures(out)
    for path in paths:
        sys.stdout.write(f"{path}\n")
    return EXIT_OK


# --- the parser and main --------------------------------------------------------------------

BUILTIN_COMMANDS = (register_simulate, register_schema, register_figures)


def _serve(sp: SubParsers) -> None:
    from service.cli import serve

    serve.register(sp)


def _feed(sp: SubParsers) -> None:
    from service.cli import clients

    clients.register_feed(sp)


def _feed_measured(sp: SubParsers) -> None:
    from service.cli import clients

    clients.register_feed_measured(sp)


def _synthesize(sp: SubParsers) -> None:
    from service.cli import clients

    clients.register_synthesize(sp)


def _replay(sp: SubParsers) -> None:
    from service.cli import replay

    replay.register(sp)


def _diagnose(sp: SubParsers) -> None:
    from service.cli import diagnose

    diagnose.register(sp)


def _recover(sp: SubParsers) -> None:
    from service.cli import recover

    recover.register(sp)


def _demo(sp: SubParsers) -> None:
    from service.cli import demo

    demo.register(sp)


def _warm(sp: SubParsers) -> None:
    from service.cli import warm

    warm.register(sp)


def _router(sp: SubParsers) -> None:
    from service.cli import router

    router.register(sp)


def _reanalyse(sp: SubParsers) -> None:
    from service.cli import reanalyse

    reanalyse.register(sp)


def _study(sp: SubParsers) -> None:
    from service.cli import study

    study.register(sp)


def _calibrate(sp: SubParsers) -> None:
    from service.cli import calibrate

    calibrate.register(sp)


def _fleet(sp: SubParsers) -> None:
    from service.cli import fleet

    fleet.register(sp)


SERVICE_COMMANDS: dict[str, Callable[[SubParsers], None]] = {
    "serve": _serve,
    "feed": _feed,
    "feed-measured": _feed_measured,
    "synthesize": _synthesize,
    "replay": _replay,
    "diagnose": _diagnose,
    "calibrate": _calibrate,
    "recover": _recover,
    "demo": _demo,
    "warm": _warm,
    "router": _router,
    "fleet": _fleet,
    "reanalyse": _reanalyse,
    "study": _study,
}
"""The service's subcommands, by name, each registered by a function that imports its module
when called: a command line that names one (``railtwin diagnose ...``) imports only that
module, so it does not pay for the others' imports (zenoh, MCAP, Rerun); any other command
line (help, a built-in command, a typo) registers them all, in this order."""


def _requested_command(argv: Sequence[str] | None) -> str | None:
    """The subcommand named on the command line (the first argument not an option)."""
    args = sys.argv[1:] if argv is None else list(argv)
    for a in args:
        if a == "--":
            return None
        if not a.startswith("-"):
            return a
    return None


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The parser: built-in commands and those of the optional modules present.

    When ``argv`` names a subcommand of one of the optional modules (a module
    ``service.cli.NAME`` registers the subcommand NAME), only that module is imported:
    ``railtwin diagnose`` does not pay for the service's imports (zenoh, MCAP, Rerun).
    Any other command line (help, a built-in command, a typo) gets them all.
    """
    from importlib.metadata import PackageNotFoundError, version

    try:
        pkg_version = version("railtwin")
    except PackageNotFoundError:
        pkg_version = "unknown (not installed)"

    parser = _Parser(
        prog=PROG,
        description=(
            "railtwin: a streaming digital twin of the wheel/rail contact "
            "(vibro-impact rolling, Hertzian and elastic-plastic contact)."
        ),
        epilog=EXIT_CODES_HELP + "\nRun 'railtwin COMMAND --help' for a command's options.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {pkg_version}")
    parser.add_argument(
        "--debug", action="store_true", help="print the traceback of runtime failures"
    )
    # _Parser is an ArgumentParser: the subcommands' register() take the plain type
    subparsers = cast(
        SubParsers, parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    )
    subparsers.required = True
    for register in BUILTIN_COMMANDS:
        register(subparsers)
    wanted = _requested_command(argv)
    for name in [wanted] if wanted in SERVICE_COMMANDS else list(SERVICE_COMMANDS):
        SERVICE_COMMANDS[name](subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``railtwin`` script; returns the exit status."""
    parser = build_parser(argv)
    args = parser.parse_args(argv)
    args.debug = getattr(args, "debug", False)
    try:
        code: int = args.func(args)
    except CommandError as exc:
        _report(exc, args)
        return exc.code
    except KeyboardInterrupt:
        sys.stderr.write(f"{PROG}: interrupted\n")
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        # stdout closed early (e.g. piped into head): not an error of ours
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_OK
    return code


QUICK_EXIT_COMMANDS = frozenset({"diagnose"})
"""One-shot commands that leave without the interpreter's teardown. Freeing the compiled
physics and its modules at exit took 0.13 s of ``railtwin diagnose``'s ~1 s (measured on
W06 of the wide set); these commands hold no child, file or lock that needs an exit
handler, so after their output is flushed they end with ``os._exit``."""


def run() -> NoReturn:
    """The ``railtwin`` console script: ``main()``, then exit with its status."""
    argv = sys.argv[1:]
    code = main(argv)
    if _requested_command(argv) in QUICK_EXIT_COMMANDS:
        for stream in (sys.stdout, sys.stderr):
            # a closed pipe or a full disk: nothing more can be said there
            with contextlib.suppress(OSError):
                stream.flush()
        logging.shutdown()
        os._exit(code)
    sys.exit(code)


def _report(exc: CommandError, args: argparse.Namespace) -> None:
    if getattr(args, "format", "table") == "json" and exc.report is not None:
        sys.stderr.write(exc.report.model_dump_json() + "\n")
    else:
        sys.stderr.write(f"{PROG} {args.command}: {exc}\n")


if __name__ == "__main__":
    run()
