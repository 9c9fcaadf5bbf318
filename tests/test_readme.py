"""README documents every `vesicle` subcommand (the CLI is the source; this fails when one is added unseen)."""

import argparse
from pathlib import Path

from vesicle_core.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]


def test_every_subcommand_is_in_the_readme():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    readme = (ROOT / "README.md").read_text()
    missing = [name for name in sub.choices if f"vesicle {name}" not in readme]
    assert not missing, f"README.md does not show: {missing}"
