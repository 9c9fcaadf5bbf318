"""argparse converters shared by the ``vesicle`` subcommands: bad values name the argument and its range."""

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
