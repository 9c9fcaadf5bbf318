"""argparse converters shared by the ``vesicle`` subcommands: bad values name the argument and its range.

Each ``type=`` converter raises argparse.ArgumentTypeError, so argparse prints the usage and exits with status 2.
"""

import argparse


def int_in(name, lo, hi):
    def conv(s):
        try:
            v = int(s)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be an integer in [{lo}, {hi}], got {s!r}") from None
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"{name} must be an integer in [{lo}, {hi}], got {v}")
        return v

    return conv


def positive_float(name):
    def conv(s):
        try:
            v = float(s)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number > 0, got {s!r}") from None
        if not v > 0:
            raise argparse.ArgumentTypeError(f"{name} must be > 0, got {s!r}")
        return v

    return conv


def finite_float(name):
    def conv(s):
        try:
            v = float(s)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {s!r}") from None
        if v != v or v in (float("inf"), float("-inf")):
            raise argparse.ArgumentTypeError(f"{name} must be a finite number, got {s!r}")
        return v

    return conv


def parse_set(items):
    """``--set KEY=VALUE`` items -> {key: value}, each value read as YAML (numbers, booleans, null, text)."""
    import yaml

    out = {}
    for it in items or []:
        if "=" not in it:
            raise argparse.ArgumentTypeError(f"--set expects KEY=VALUE, got {it!r}")
        k, v = it.split("=", 1)
        val = yaml.safe_load(v)
        if isinstance(val, str):  # YAML 1.1 reads "2e-05" (no dot) as a string; Python writes floats that way
            try:
                val = float(val)
            except ValueError:
                pass
        out[k.strip()] = val
    return out
