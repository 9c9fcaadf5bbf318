"""The ``vesicle`` command: mesh|run|decompose|theory|fit|microscope|figures|catalog|report|bench|params.

Every step of the Snakemake workflow calls one of these subcommands, so each can also be run by
hand. Bad arguments exit with status 2 and a message that names the argument and its allowed range.

The subcommands live by purpose: :mod:`vesicle_core.cli.sim` (mesh, run, bench, params),
:mod:`vesicle_core.cli.analysis` (decompose, theory, fit), :mod:`vesicle_core.cli.microscopy` (microscope) and
:mod:`vesicle_core.cli.post` (figures, catalog, report); the argument converters are in
:mod:`vesicle_core.cli.args`. This module builds the parser and maps errors to exit statuses.
"""

from __future__ import annotations

import argparse
import os
import sys

from ..errors import NumericalInstability, VesicleError
from . import analysis as cli_analysis
from . import microscopy as cli_microscopy
from . import noise as cli_noise
from . import post as cli_post
from . import sim as cli_sim


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse's default prints usage; keep that, and name the command
        self.print_usage(sys.stderr)
        self.exit(2, f"{self.prog}: error: {message}\n")


# in this order in ``vesicle --help``
_ADDERS = [
    cli_sim.add_mesh, cli_sim.add_run, cli_analysis.add_decompose, cli_analysis.add_theory, cli_analysis.add_fit,
    cli_microscopy.add_microscope, cli_microscopy.add_pattern_claims,
    cli_post.add_report, cli_sim.add_bench, cli_sim.add_params, cli_post.add_figures, cli_post.add_catalog,
    cli_noise.add_stochastic_pa, cli_noise.add_noise,
]


def build_parser():
    parser = _Parser(prog="vesicle", description=__doc__.splitlines()[0])
    from .. import __version__

    parser.add_argument("--version", action="version", version=f"vesicle_core {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for add in _ADDERS:
        add(sub)
    return parser


def main(argv=None):
    # spinning OpenBLAS threads slowed the FFT 5-10x on the reference machine; the solver uses no BLAS-heavy code
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args) or 0
    except VesicleError as exc:
        print(f"vesicle {args.command}: error: {exc}", file=sys.stderr)
        return 3 if isinstance(exc, NumericalInstability) else 2
    except KeyboardInterrupt:  # SIGINT or SIGTERM; a run has checkpointed and says how to resume
        print(f"vesicle {args.command}: interrupted", file=sys.stderr)
        return 130
