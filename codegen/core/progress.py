"""Progress shown where it can be read: a tqdm bar on a terminal, whole lines on anything else (a
log file, a pipe, CI), so that no bar's carriage returns glue themselves to the next message.

``bar(...)`` takes tqdm's arguments and returns a tqdm bar when ``file`` is a terminal, otherwise a
``Lines``: the same calls (``update``, ``set_postfix_str``, ``set_description``, iteration, a
``with`` block), each shown as one line ``desc: n/total unit (postfix)`` when the postfix or the
description changes, and at most every ``LINE_SECONDS`` otherwise.
"""
from __future__ import annotations

import sys
import time

LINE_SECONDS = 10.0          # the longest a non-terminal goes without a line while a bar moves


def is_terminal(file):
    """True when ``file`` is an interactive terminal (isatty)."""
    try:
        return bool(file.isatty())
    except (AttributeError, ValueError):
        return False


def bar(iterable=None, desc=None, total=None, unit="it", file=None, disable=False, **options):
    """A progress bar (module docstring) over ``iterable`` (or updated by hand), ``desc`` before its
    count of ``total`` ``unit``, on ``file`` (default stderr): tqdm's on a terminal, ``Lines``
    otherwise; ``disable`` True shows nothing (tqdm's None: nothing off a terminal, as here).
    Other ``options`` go to tqdm (``leave``, ``miniters``, ...)."""
    file = sys.stderr if file is None else file
    if is_terminal(file):
        from tqdm import tqdm
        return tqdm(iterable, desc=desc, total=total, unit=unit, file=file, disable=bool(disable), **options)
    return Lines(iterable, desc=desc, total=total, unit=unit, file=file, disable=disable is not False)


class Lines:
    """A progress bar as whole lines (module docstring)."""

    def __init__(self, iterable=None, desc=None, total=None, unit="it", file=None, disable=False):
        self.iterable, self.desc, self.unit, self.file = iterable, desc, unit, file or sys.stderr
        self.total = total if total is not None else (len(iterable) if hasattr(iterable, "__len__") else None)
        self.n, self.postfix, self.disable = 0, "", bool(disable)
        self._shown, self._at = None, time.monotonic()

    def __str__(self):
        count = f"{self.n}/{self.total}" if self.total is not None else f"{self.n}"
        return (f"{self.desc}: " if self.desc else "") + f"{count} {self.unit}" + (f" ({self.postfix})" if self.postfix else "")

    def _show(self, changed=False):
        now = time.monotonic()
        if self.disable or not (changed or now - self._at >= LINE_SECONDS):
            return
        text = str(self)
        if text != self._shown:
            self.file.write(text + "\n")
            self.file.flush()
            self._shown, self._at = text, now

    def update(self, n=1):
        """``n`` more done (a line when LINE_SECONDS have passed since the last)."""
        self.n += n
        self._show()

    def set_postfix_str(self, s="", refresh=True):
        """The text ``s`` after the count (a line when it changes; ``refresh`` is tqdm's, unused)."""
        changed = str(s) != self.postfix
        self.postfix = str(s)
        self._show(changed)

    def set_postfix(self, ordered_dict=None, refresh=True, **kwargs):
        """tqdm's ``set_postfix``: the ``name=value`` pairs of ``ordered_dict`` and ``kwargs`` after the
        count (``refresh`` unused)."""
        items = {**(ordered_dict or {}), **kwargs}
        self.set_postfix_str(", ".join(f"{k}={v}" for k, v in items.items()))

    def set_description(self, desc=None, refresh=True):
        """The text ``desc`` before the count (a line when it changes; ``refresh`` unused)."""
        changed = desc != self.desc
        self.desc = desc
        self._show(changed)

    def refresh(self):
        """Nothing to redraw: lines are written as they come."""

    def write(self, s, file=None):
        """A message line ``s`` on ``file`` (default the bar's; tqdm.write's)."""
        (file or self.file).write(f"{s}\n")

    def close(self):
        """The end: nothing more (the last line stays as written)."""
        self.disable = True

    def __iter__(self):
        for item in self.iterable:
            yield item
            self.update()

    def __len__(self):
        return self.total or 0

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False
