"""``whitted render --scheduler``: USD frames and tiles on a Dask cluster (see :mod:`tracer.farm`).

Workers read the stage from its path (a shared filesystem: the same absolute path on every machine), or, with
``--ship-assets``, from a .usdz package the client builds of the stage and every asset it resolves (UsdUtils) and
sends to each worker once. The client writes every output file (atomically, as a local render does), or with
``--worker-writes`` the workers do. A worker reads the stage from the same :class:`usd_io.request.StageRequest`
(:class:`UsdSource` is one) and renders with the same :class:`tracer.RenderSettings` as a local render, and writes
through the same :class:`usd_io.outputs.Outputs`: nothing is copied field by field, so nothing can drift.
"""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile
import threading
from dataclasses import dataclass, field, fields, replace

from .errors import UsdInputError
from .outputs import Outputs, frame_path
from .request import StageRequest

#: Scheduler address forms: a Dask address, ``local:N``, or a scheduler file written by ``dask scheduler``.
ADDRESS_SCHEMES = ("tcp://", "tls://", "ws://", "wss://", "inproc://", "ucx://")


@dataclass(frozen=True)
class UsdSource(StageRequest):
    """A USD stage as a farm scene source: ``load(frame) -> (tracer.Scene, RenderSettings)`` on the worker.

    Every field of :class:`usd_io.request.StageRequest` (camera, width, height, purposes, variants, complexity,
    ...), read as a local ``whitted render`` reads it. ``settings`` (a :class:`tracer.RenderSettings`, or a dict of
    its fields) are the render settings except the image size, which comes from the stage's camera and the
    requested width/height."""

    settings: object = field(default_factory=dict, hash=False, compare=False)
    #: sha256 of the shipped package this source was unpacked from (None: read ``path`` itself).
    package: str | None = None

    @classmethod
    def of(cls, request: StageRequest, settings) -> "UsdSource":
        """The farm source of a stage request (its path made absolute) and render settings."""
        values = {f.name: getattr(request, f.name) for f in fields(StageRequest)}
        values["path"] = os.path.abspath(request.path)
        return cls(**values, settings=settings)

    def tracer_settings(self):
        """``settings`` as :class:`tracer.RenderSettings` (the stage decides the image size at ``load``)."""
        from tracer import RenderSettings

        return self.settings if isinstance(self.settings, RenderSettings) else RenderSettings(**self.settings)

    def load(self, frame):
        scene, info = self.at(frame).read(_open(self.path).stage)
        return scene, self.tracer_settings().with_(width=info.width, height=info.height)

    def scene_key(self, frame):
        """What :func:`tracer.farm.prepare` keys a worker's prepared scene by (with this source's own fields): the
        stamp of every file the stage is made of (path, size, modification time and inode of each layer USD
        opened for it), and the frame only when some layer has time samples. So the frames of a still stage share
        one prepared scene, an animated stage reads each frame, and a stage changed on disk is read again."""
        opened = _open(self.path)
        return opened.stamp, (frame if opened.animated else None)

    def unpacked(self, assets: bytes) -> "UsdSource":
        """This source reading the package ``assets`` (written once per worker to a temporary file)."""
        digest = hashlib.sha256(assets).hexdigest()
        path = os.path.join(tempfile.gettempdir(), f"whitted-farm-{digest[:24]}.usdz")
        with _write_lock:
            if not os.path.exists(path):
                tmp = f"{path}.{os.getpid()}.part"
                with open(tmp, "wb") as f:
                    f.write(assets)
                os.replace(tmp, path)
        return replace(self, path=path, package=digest)


@dataclass(frozen=True)
class WriteFrames:
    """``--worker-writes``: a worker writes its frame (and AOVs) itself, atomically, to ``pattern`` — an absolute path
    on a filesystem every worker shares — through the same :class:`usd_io.outputs.Outputs` as the client."""

    pattern: str
    many: bool
    outputs: Outputs = Outputs()

    def __call__(self, image, frame):
        try:
            self.outputs.write(image, frame_path(self.pattern, frame, self.many))
        except UsdInputError as exc:  # an unwritable path on this worker: the frame's error, in one line
            raise OSError(str(exc)) from None


@dataclass(frozen=True)
class FarmOptions:
    """How ``whitted render --scheduler`` runs: the scheduler address, whether the workers write the frames
    themselves (``--worker-writes``) and read a shipped package (``--ship-assets``), and ``quiet``."""

    scheduler: str
    worker_writes: bool = False
    ship_assets: bool = False
    quiet: bool = False


_write_lock = threading.Lock()
_stages: dict = {}
_stages_lock = threading.Lock()


@dataclass(frozen=True)
class _Opened:
    """A worker's open stage, the stamp of the files it was read from, and whether any of them has time samples."""

    stage: object
    stamp: tuple
    animated: bool


def _open(path) -> _Opened:
    """The worker's open stage for ``path``: opened once per worker process, and opened again (its changed layers
    reloaded) when a file it is made of changed on disk since (the stamps of :func:`_stamp` differ)."""
    from .stage import open_stage

    with _stages_lock:
        opened = _stages.get(path)
        if opened is not None:
            now = _stamp(opened.stage)
            if now == opened.stamp:
                return opened
            changed = {p for p, *rest in set(now) ^ set(opened.stamp)}
            for layer in opened.stage.GetUsedLayers():  # USD's layer registry would hand back the old contents
                if _file_of(layer) in changed:
                    layer.Reload(force=True)
            del _stages[path]
        stage = open_stage(path)
        animated = any(layer.ListAllTimeSamples() or _has_clips(layer) for layer in stage.GetUsedLayers())
        opened = _stages[path] = _Opened(stage, _stamp(stage), animated)
        return opened


def _has_clips(layer) -> bool:
    """Whether a prim of ``layer`` names value clips (their layers, and so their time samples, are opened only
    when a value is read: a stage that uses them counts as animated)."""
    found = []

    def visit(path):
        if not found and path.IsPrimPath():
            spec = layer.GetPrimAtPath(path)
            if spec is not None and (spec.HasInfo("clips") or spec.HasInfo("clipAssetPaths")):
                found.append(path)

    layer.Traverse(layer.pseudoRoot.path, visit)
    return bool(found)


def _file_of(layer) -> str | None:
    """The file a layer was read from (a package's file for a layer inside a .usdz), None for anonymous layers."""
    path = layer.realPath
    if not path:
        return None
    from pxr import Ar

    outer, _inner = Ar.SplitPackageRelativePathOuter(path)
    return outer or path


def _stamp(stage) -> tuple:
    """(file, size, mtime_ns, inode) of every file the stage's layers were read from, sorted."""
    out = set()
    for layer in stage.GetUsedLayers():
        path = _file_of(layer)
        if path is None:
            continue
        try:
            st = os.stat(path)
            out.add((path, st.st_size, st.st_mtime_ns, st.st_ino))
        except OSError:
            out.add((path, None, None, None))
    return tuple(sorted(out, key=lambda r: r[0]))


def package_assets(path: str) -> bytes:
    """The stage at ``path`` and every layer and asset it resolves, as one .usdz package (bytes)."""
    from pxr import Sdf, UsdUtils

    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "package.usdz")
        if not UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(os.path.abspath(path)), out):
            raise UsdInputError(f"{path}: could not package the stage and its assets for --ship-assets")
        with open(out, "rb") as f:
            return f.read()


def connect(address: str):
    """A Dask client for ``address`` -> (client, cluster or None, threads per task or None).

    ``local:N`` starts a LocalCluster of N single-threaded worker processes bound to 127.0.0.1 (dashboard too);
    an address ``tcp://``/``tls://``/… connects to a running scheduler, with Dask's security configuration
    (``distributed.comm.tls.*``) for TLS; anything else is read as a scheduler file."""
    try:
        from dask.distributed import Client
    except ImportError:
        raise UsdInputError("--scheduler needs Dask: pip install 'whitted[farm]' (dask[distributed])") from None

    if address.startswith("local:") or address == "local":
        n = address.partition(":")[2] or str(os.cpu_count() or 1)
        if not n.isdigit() or int(n) < 1:
            raise UsdInputError(f"--scheduler {address!r}: expected local:N with N >= 1 workers")
        n = int(n)
        from tracer.farm import local_cluster  # one-thread workers configured for rendering (WORKER_CONFIG)

        client, cluster = local_cluster(n)
        return client, cluster, max(1, (os.cpu_count() or 1) // n)
    if address.startswith(ADDRESS_SCHEMES):
        if address.startswith("tls://"):
            import dask

            if not dask.config.get("distributed.comm.tls.client.cert", None) and \
                    not dask.config.get("distributed.comm.tls.ca-file", None):
                raise UsdInputError(f"--scheduler {address}: tls:// needs Dask's TLS configuration "
                                     "(distributed.comm.tls.ca-file and client cert/key)")
        try:
            return Client(address, timeout="20s"), None, None
        except OSError as exc:
            raise UsdInputError(f"--scheduler {address}: cannot reach the scheduler ({exc})") from None
    if os.path.isfile(address):
        try:
            return Client(scheduler_file=address, timeout="20s"), None, None
        except (OSError, ValueError) as exc:
            raise UsdInputError(f"--scheduler {address}: cannot use this scheduler file ({exc})") from None
    raise UsdInputError(f"--scheduler {address!r}: expected tcp://HOST:PORT, tls://HOST:PORT, local:N "
                         "or a scheduler file")


def render_on_farm(request: StageRequest, settings, frames, output: str, outputs: Outputs,
                   farm: FarmOptions) -> int:
    """The CLI's farm path: frames (one task each) or, for a single frame, tiles; returns the exit code.

    ``frames`` are time codes (``[None]`` for the stage's default time), ``output`` the output pattern
    (:func:`usd_io.outputs.frame_path` names each frame); ``outputs`` writes each image, on the client or, with
    ``farm.worker_writes``, on the workers."""
    from tqdm import tqdm

    from tracer.farm import render_frames, render_tiled

    source = UsdSource.of(request, settings.with_(progress=False))
    assets = package_assets(source.path) if farm.ship_assets else None
    many = len(frames) > 1
    client, cluster, threads = connect(farm.scheduler)
    if threads is not None and settings.threads is None:
        source = replace(source, settings=source.settings.with_(threads=threads))
    quiet = farm.quiet
    try:
        if not quiet and client.dashboard_link:
            print(f"whitted: Dask dashboard: {client.dashboard_link}", file=sys.stderr)
        failed = 0
        if len(frames) == 1:
            bar = None if quiet else tqdm(unit="tile", desc="whitted farm", leave=False)
            image = render_tiled(client, source, frames[0], assets=assets,
                                 on_tile=(lambda t: bar.update(1)) if bar is not None else None)
            if bar is not None:
                bar.close()
            outputs.write(image, frame_path(output, frames[0], many))
        else:
            bar = None if quiet else tqdm(total=len(frames), unit="frame", desc="whitted farm", leave=False)
            worker_write = WriteFrames(os.path.abspath(output), many, outputs) if farm.worker_writes else None
            for res in render_frames(client, source, frames, assets=assets, write=worker_write):
                if res.error is not None:
                    failed += 1
                    print(f"whitted: error: frame {res.frame:g}: {res.error}", file=sys.stderr)
                elif res.image is not None:
                    outputs.write(res.image, frame_path(output, res.frame, many))
                if bar is not None:
                    bar.update(1)
            if bar is not None:
                bar.close()
        if failed:
            print(f"whitted: {failed} of {len(frames)} frame(s) failed", file=sys.stderr)
            return 2
        return 0
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
