"""Errors a user can fix. The CLI turns these into one line on stderr and exit status 2."""

from __future__ import annotations

import re
from collections.abc import Iterable

MAX_LINE = 300  # characters of a refusal's line, ``optcal CMD: error: ...`` included


class InputError(ValueError):
    """Bad input (data, options, names): the message names the problem and the fix, in one line."""


class BudgetExhausted(Exception):
    """Raised by a problem when its evaluation, time or target budget is used up."""


def listing(items: Iterable, limit: int = 8, sep: str = ", ") -> str:
    """``items`` joined by ``sep`` for a message, cut after the first ``limit``: ``a, b, c, … (59 more)``, so
    that a file of many columns keeps its refusal one short line."""
    items = [str(x) for x in items]
    if len(items) <= limit + 1:  # "… (1 more)" would be no shorter than the item it hides
        return sep.join(items)
    return f"{sep.join(items[:limit])}{sep}… ({len(items) - limit} more)"


_FOLDERS = re.compile(r"(?<![\w.])(?:[A-Za-z]:)?[/\\](?:[^\s/\\:;,'\"]+[/\\])+(?=[^\s/\\]+)")  # /a/b/ of /a/b/c.csv
CLAUSE = 60  # characters a clause keeps at least when a long message is shortened


def _squeeze(text: str, n: int, head_share: float = 0.5) -> str:
    """``text`` cut to at most ``n`` characters by its middle, at spaces, with " … " between its start (about
    ``head_share`` of what is kept) and its end."""
    room = n - 3  # " … "
    head = text[:int(room * head_share)]
    head = head.rsplit(" ", 1)[0] if " " in head else head
    start = len(text) - (room - len(head))
    if not text[start - 1].isspace() and " " in text[start:]:
        start = text.index(" ", start) + 1
    return f"{head} … {text[start:]}"


def one_line(message: str, limit: int = MAX_LINE) -> str:
    """``message`` on one line of at most ``limit`` characters, a backstop (messages are cut where they are
    made: :func:`listing`): newlines, and the spaces around them, become one space. A longer message, in
    turn until it fits: names its files without their folders (``…/rec.csv``); cuts the details after the
    first colon of its first clause (the counts or evidence after the problem is named), down to "…"; cuts
    the middle of its other clauses (the parts between semicolons) but the last (the way out), the longest
    first, down to :data:`CLAUSE` characters; then its own middle, with "…" there."""
    text = re.sub(r"\s*[\r\n]+\s*", " ", str(message)).strip()
    if len(text) > limit:
        text = _FOLDERS.sub("…/", text)
    clauses = text.split("; ")
    problem, colon, details = clauses[0].partition(": ")
    if len(text) > limit and colon and len(details) >= CLAUSE:
        keep = len(details) - (len(text) - limit)
        clauses[0] = problem + ": " + (_squeeze(details, keep) if keep >= CLAUSE // 2 else "…")
        text = "; ".join(clauses)
    while len(text) > limit and len(clauses) > 2:
        k = max(range(1, len(clauses) - 1), key=lambda i: len(clauses[i]) if "…" not in clauses[i] else 0)
        c = clauses[k]
        if "…" in c or len(c) <= CLAUSE:
            break
        clauses[k] = _squeeze(c, max(CLAUSE, len(c) - (len(text) - limit)))
        text = "; ".join(clauses)
    return text if len(text) <= limit else _squeeze(text, limit, 0.4)
