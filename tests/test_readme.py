"""README is the newcomer's first page: it documents every `vesicle` subcommand (the CLI is the source; this fails
when one is added unseen), stays short, and shows the tiny run before the default job."""

import argparse
import re
from pathlib import Path

from vesicle_core.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"

#: the commands CI runs as README's (.ci/run): the tiny workflow, the default job and the test command
TINY_RUN = "snakemake --cores 2 all --configfile config/tiny.yaml"
DEFAULT_JOB = 'pip install -e ".[workflow,fast]" && snakemake --cores 2 all\n'
TEST_COMMAND = 'pip install -e ".[test]" && pytest\n'
#: measurements and long reference material belong in docs/ (README links to them)
MAX_LINES = 130


def test_every_subcommand_is_in_the_readme():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    readme = README.read_text()
    missing = [name for name in sub.choices if f"vesicle {name}" not in readme]
    assert not missing, f"README.md does not show: {missing}"


def test_readme_is_short():
    n = len(README.read_text().splitlines())
    assert n < MAX_LINES, f"README.md has {n} lines (< {MAX_LINES}): move details to docs/ and link them"


def test_tiny_run_comes_before_the_default_job():
    readme = README.read_text()
    for command in (TINY_RUN, DEFAULT_JOB, TEST_COMMAND):
        assert command in readme, f"README.md lacks {command.strip()!r}"
    assert readme.index(TINY_RUN) < readme.index(DEFAULT_JOB), "the tiny run must be the first workflow command"
    first_snakemake = readme.index("snakemake --cores")
    assert first_snakemake == readme.index(TINY_RUN), "the first snakemake command in README.md must be the tiny run"


def test_readme_links_resolve():
    """Relative links and images in README.md point at files of the repository."""
    readme = README.read_text()
    targets = re.findall(r"\]\(([^)#]+)\)", readme)
    missing = [t for t in targets if "://" not in t and not (ROOT / t).exists()]
    assert not missing, f"README.md links to missing files: {missing}"
