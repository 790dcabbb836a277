"""Opening a stage and walking the prims a render sees.

Composition is USD's own (references, payloads, sublayers, variants, ``.usdz``) through the default resolver.
Traversal follows instance proxies (native instancing is flattened), skips inactive and abstract prims, prims whose
computed visibility is ``invisible`` at the time code, and prims whose computed purpose is not in ``purposes``.
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
import tempfile

from pxr import Sdf, Usd, UsdGeom

from .diagnostics import summarize
from .errors import UsdInputError  # noqa: F401  (raised here; usd_io.stage.UsdInputError stays importable)
from .materials.mtlx import resolve_mtlx_references

#: The purposes a render includes by default (usdrecord's default is the same pair).
DEFAULT_PURPOSES = ("default", "render")
KNOWN_PURPOSES = ("default", "render", "proxy", "guide")


@contextlib.contextmanager
def captured_stderr():
    """Capture what C++ code (USD's TF diagnostics) writes to file descriptor 2; yields a list that receives the
    captured text. The reader reports composition problems itself, once each, instead."""
    out: list[str] = []
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield out
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            out.append(tmp.read().decode("utf-8", "replace"))


def open_stage(path_or_stage) -> Usd.Stage:
    """A ``Usd.Stage`` from a path (everything loaded, payloads included) or an already-open stage."""
    if isinstance(path_or_stage, Usd.Stage):
        resolve_mtlx_references(path_or_stage)
        return path_or_stage
    path = os.fspath(path_or_stage)
    if not os.path.exists(path):
        raise UsdInputError(f"{path}: no such file")
    if os.path.isdir(path):
        raise UsdInputError(f"{path}: is a directory, not a USD file")
    if not Sdf.FileFormat.FindByExtension(os.path.splitext(path)[1].lstrip(".").lower() or "-"):
        raise UsdInputError(f"{path}: not a USD file (unknown extension {os.path.splitext(path)[1]!r})")
    stage, detail = None, ""
    with captured_stderr() as text:
        try:
            stage = Usd.Stage.Open(path, Usd.Stage.LoadAll)
        except Exception as exc:  # pxr raises Tf.ErrorException with a multi-line message
            detail = _first_reason(str(exc))
        if stage is not None:
            resolve_mtlx_references(stage)  # .mtlx references: usd-core cannot read them (usd_io.materials.mtlx)
    if stage is None:
        detail = detail or _first_reason("".join(text))
        raise UsdInputError(f"{path}: not a readable USD file" + (f" ({detail})" if detail else ""))
    # Composition problems are reported by composition_warnings(); anything else USD said is kept for the reader.
    other = [ln for ln in "".join(text).splitlines()
             if ln.strip() and "_ReportErrors" not in ln and "Could not open asset" not in ln]
    stage_messages[id(stage)] = summarize("\n".join(other))  # a few lines, as the reader's (usd_io.diagnostics)
    return stage


#: Diagnostics USD printed while opening a stage (keyed by id(stage)), minus composition errors.
stage_messages: dict[int, list[str]] = {}


def _first_reason(text: str) -> str:
    """The first human part of a USD error: the quoted reason of "Error in '...' at line N in file F : 'why'"."""
    m = re.search(r"([^\s']+:\d+:\d+: [^\n]*)", text)  # the parser's own FILE:LINE:COL: message comes first
    if m:
        return " ".join(m.group(1).split())[:300]
    m = re.search(r"Error in '[^']*' at line \d+ in file \S+ : '(.*?)'\s*(?:$|\n)", text, re.M)
    if m:
        return " ".join(m.group(1).split())[:200]
    for ln in text.splitlines():
        ln = re.sub(r"^(Error|Warning|Coding Error|Runtime Error):? in \S+ at line \d+ of \S+ -- ", "", ln.strip())
        if ln:
            return " ".join(ln.split())[:200]
    return ""


def composition_warnings(stage: Usd.Stage) -> list[str]:
    """One line per distinct composition problem: an asset that could not be opened is reported once, with the
    prims that asked for it (the rest of the stage still renders)."""
    missing: dict[str, list[str]] = {}
    out = []
    for err in stage.GetCompositionErrors():
        msg = " ".join(str(err).split())
        m = re.search(r"Could not open asset @([^@]*)@ for (\w+) introduced by @[^@]*@<([^>]*)>", msg)
        if m:
            missing.setdefault(f"{m.group(2)} @{m.group(1)}@", []).append(m.group(3))
        elif f"composition: {msg}" not in out:
            out.append(f"composition: {msg}")
    for what, prims in missing.items():
        shown = ", ".join(prims[:3]) + (f" and {len(prims) - 3} more" if len(prims) > 3 else "")
        out.insert(0, f"composition: could not open {what} (needed by {shown}); rendering what resolves")
    return out


def check_purposes(purposes) -> tuple[str, ...]:
    purposes = tuple(purposes)
    bad = [p for p in purposes if p not in KNOWN_PURPOSES]
    if bad:
        raise UsdInputError(f"unknown purpose(s) {bad}; choose from {', '.join(KNOWN_PURPOSES)}")
    return purposes


def renderable_prims(stage: Usd.Stage, time: Usd.TimeCode, purposes=DEFAULT_PURPOSES, root=None):
    """Yield prims (of the stage, or of the subtree at ``root``, root included) to convert: active, defined, non-abstract, visible at ``time``, of a wanted purpose.

    Subtrees are pruned at the first invisible prim and below PointInstancers (their prototypes are drawn only
    through the instancer). A prim's purpose is its own authored one, else its nearest ancestor's
    (UsdGeomImageable's ComputePurpose, as Storm draws them): a prim of an unwanted purpose is left out, but its
    descendants that author a wanted purpose are not. A Skeleton is yielded whatever its purpose (its bones'
    purpose is a guide unless authored: usd_io.geometry.skel.skeleton_purpose). Instance proxies are included. Under a ``root`` (a
    PointInstancer's prototype) a ``def`` counts even when an ancestor is an ``over``: prototypes kept under an
    ``over`` so that they do not render on their own are drawn through their instancer, as Hydra draws them.
    """
    defined = Usd.PrimIsDefined if root is None else Usd.PrimHasDefiningSpecifier
    predicate = Usd.TraverseInstanceProxies(Usd.PrimIsActive & defined & ~Usd.PrimIsAbstract)
    it = iter(Usd.PrimRange(root if root is not None else stage.GetPseudoRoot(), predicate))
    infos: dict = {}  # prim path -> UsdGeom purpose info (its children's inheritance)
    if root is None:
        next(it)  # the pseudo-root
    for prim in it:
        img = UsdGeom.Imageable(prim)
        if img:
            vis = img.GetVisibilityAttr().Get(time)
            if vis == UsdGeom.Tokens.invisible:
                it.PruneChildren()
                continue
            parent = infos.get(prim.GetParent().GetPath())
            info = img.ComputePurposeInfo(parent) if parent is not None else img.ComputePurposeInfo()
            infos[prim.GetPath()] = info
            if info.purpose not in purposes and prim.GetTypeName() != "Skeleton":
                if prim.IsA(UsdGeom.PointInstancer):
                    it.PruneChildren()
                continue
        yield prim
        if prim.IsA(UsdGeom.PointInstancer):
            it.PruneChildren()



def stage_time(stage: Usd.Stage, time) -> Usd.TimeCode:
    """``None`` -> the earliest time (the default value where no samples exist, else the first sample)."""
    if time is None:
        return Usd.TimeCode.EarliestTime()
    if isinstance(time, Usd.TimeCode):
        return time
    return Usd.TimeCode(float(time))
