"""Decoder settings from a benchmark's command line: ``KEY=VALUE`` pairs into :class:`DetectorParams`.

A benchmark that takes ``--params KEY=VALUE ...`` (or ``--other``) reads its frames with our
decoder under those settings, so what a setting saves and what it gives up are measured on the
same frames as the defaults, e.g. ``--params last_resort_passes=false model_match=false``.
Values: ``true``/``false`` for switches, numbers, and comma-separated names for
``polarities``.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Sequence
from typing import Any

from ottag_db.decode import DetectorParams
from ottag_db.errors import UsageError

_DEFAULTS = DetectorParams()
_SWITCHES = {"true": True, "false": False, "1": True, "0": False, "yes": True, "no": False}


def add_params_argument(parser: argparse.ArgumentParser) -> None:
    """Give ``parser`` the option ``--params KEY=VALUE ...`` (our decoder's settings; default none)."""
    parser.add_argument(
        "--params", nargs="+", default=[], metavar="KEY=VALUE", help="our decoder's settings (benchmarks/settings.py)"
    )


def params_from(pairs: Sequence[str], parser: argparse.ArgumentParser, option: str = "--params") -> DetectorParams:
    """The decoder's settings with ``pairs`` (``KEY=VALUE``) changed from the defaults.

    Parameters
    ----------
    pairs : sequence of str
        ``KEY=VALUE`` strings, KEY a field of :class:`DetectorParams`.
    parser : argparse.ArgumentParser
        Reports a bad pair as a usage error (exit 2), naming ``option``.
    option : str, optional
        The option the pairs came from.

    Returns
    -------
    DetectorParams
    """
    fields = {f.name: f for f in dataclasses.fields(DetectorParams)}
    changes: dict[str, Any] = {}
    for pair in pairs:
        key, sep, text = pair.partition("=")
        if not sep or key not in fields:
            parser.error(f"{option}: {pair!r} is no KEY=VALUE of DetectorParams (keys: {', '.join(fields)})")
        default = getattr(_DEFAULTS, key)
        try:
            if isinstance(default, bool):
                if text.lower() not in _SWITCHES:
                    raise ValueError("true or false")
                changes[key] = _SWITCHES[text.lower()]
            elif isinstance(default, int):
                changes[key] = int(text)
            elif isinstance(default, float):
                changes[key] = float(text)
            else:  # polarities
                changes[key] = tuple(name.strip() for name in text.split(",") if name.strip())
        except ValueError:
            parser.error(f"{option}: {pair!r}: {key} takes a {type(default).__name__}")
    try:
        return dataclasses.replace(_DEFAULTS, **changes)
    except UsageError as exc:
        parser.error(f"{option}: {exc}")


def describe(params: DetectorParams) -> str:
    """The settings that differ from the defaults, as ``key=value, ...`` (``defaults`` if none)."""
    changed = [
        f"{f.name}={getattr(params, f.name)}"
        for f in dataclasses.fields(DetectorParams)
        if getattr(params, f.name) != getattr(_DEFAULTS, f.name)
    ]
    return ", ".join(changed) or "defaults"
