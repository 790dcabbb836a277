"""USD's own diagnostics (TF warnings and errors that C++ prints on stderr while a stage is read) as a few
``usd: …`` warnings instead of raw lines.

pxr prints one diagnostic as a first line (``Warning: in Func at line N of file.cpp -- message``) followed by
tab-indented continuation lines (e.g. one ``Invalid index …`` per bad index of a primvar). Each diagnostic becomes
one line: its message without the C++ location and the stage/session-layer boilerplate, its continuation lines
counted; diagnostics of the same kind (equal up to numbers) are merged with a count; at most :data:`MAX_LINES`.
``render``, ``info`` and ``explain`` all print what :func:`usd_io.load_stage` collected this way.
"""

from __future__ import annotations

import re

MAX_LINES = 5
_HEAD = re.compile(r"^(Warning|Error|Coding Error|Runtime Error|Fatal Error|Status)\b")
_LOCATION = re.compile(r"^(?:Warning|Error|Coding Error|Runtime Error|Fatal Error|Status):?\s*(?:in \S+ at line \d+ "
                       r"of \S+ -- )?")
_BOILERPLATE = re.compile(r"\s*on stage with rootLayer @[^@]*@, sessionLayer @[^@]*@:?\s*")


def summarize(text: str) -> list[str]:
    """The diagnostics in captured stderr ``text`` as at most MAX_LINES short lines."""
    entries: list[list[str]] = []
    for line in text.splitlines():
        if not line.strip():
            continue
        if line[:1] in ("\t", " ") and entries:
            entries[-1].append(line.strip())
        else:
            entries.append([line.strip()])
    groups: dict[str, list] = {}
    for head, *rest in entries:
        msg = _BOILERPLATE.sub(" ", _LOCATION.sub("", head)).strip(" :")
        if rest:
            msg = f"{msg}: {rest[0]}" + (f" (and {len(rest) - 1} more)" if len(rest) > 1 else "")
        msg = " ".join(msg.split())[:240]
        key = re.sub(r"\d+", "#", re.sub(r"<[^>]*>|'[^']*'", "…", msg))
        groups.setdefault(key, [msg, 0])[1] += 1
    out = [m if n == 1 else f"{m} (and {n - 1} like it)" for m, n in groups.values()]
    if len(out) > MAX_LINES:
        out = out[:MAX_LINES - 1] + [f"{len(out) - MAX_LINES + 1} more kinds of USD diagnostics"]
    return out
