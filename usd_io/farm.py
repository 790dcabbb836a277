"""``whitted render --scheduler``: USD frames and tiles on a Dask cluster (see :mod:`tracer.farm`).

Workers read the stage from its path (a shared filesystem: the same absolute path on every machine), or, with
``--ship-assets``, from a .usdz package the client builds of the stage and every asset it resolves (UsdUtils) and
sends to each worker once. The client writes every output file (atomically, as a local render does).
"""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile
import threading
from dataclasses import dataclass, field, replace

#: Scheduler address forms: a Dask address, ``local:N``, or a scheduler file written by ``dask scheduler``.
ADDRESS_SCHEMES = ("tcp://", "tls://", "ws://", "wss://", "inproc://", "ucx://")


class FarmInputError(ValueError):
    """A bad --scheduler / --ship-assets request (one line for the CLI)."""


@dataclass(frozen=True)
class UsdSource:
    """A USD stage as a farm scene source: ``load(frame) -> (tracer.Scene, RenderSettings)`` on the worker.

    ``settings`` are the render settings except the image size, which comes from the stage's camera and the
    requested width/height, exactly as a local ``whitted render`` computes it."""

    path: str
    camera: str | None = None
    width: int | None = None
    height: int | None = None
    purposes: tuple = ("default", "render")
    default_light: bool = True
    complexity: str = "medium"
    settings: dict = field(default_factory=dict, hash=False, compare=False)
    #: sha256 of the shipped package this source was unpacked from (None: read ``path`` itself).
    package: str | None = None

    def load(self, frame):
        from tracer import RenderSettings

        from .reader import load_stage

        scene, info = load_stage(_open(self.path), time=frame, camera=self.camera, width=self.width,
                                 height=self.height, purposes=list(self.purposes), default_light=self.default_light,
                                 complexity=self.complexity)
        return scene, RenderSettings(width=info.width, height=info.height, **self.settings)

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
    on a filesystem every worker shares."""

    pattern: str
    many: bool
    aovs: tuple = ()

    def __call__(self, image, frame):
        from .cli import BadInput, frame_path, write_outputs

        try:
            write_outputs(image, frame_path(self.pattern, frame, self.many) if frame is not None else self.pattern,
                          self.aovs)
        except BadInput as exc:  # an unwritable path on this worker: the frame's error, in one line
            raise OSError(str(exc)) from None


_write_lock = threading.Lock()
_stages: dict = {}


def _open(path):
    """The worker's open stage for ``path`` (opened once per worker process)."""
    from .stage import open_stage

    stage = _stages.get(path)
    if stage is None:
        stage = _stages[path] = open_stage(path)
    return stage


def package_assets(path: str) -> bytes:
    """The stage at ``path`` and every layer and asset it resolves, as one .usdz package (bytes)."""
    from pxr import Sdf, UsdUtils

    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "package.usdz")
        if not UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(os.path.abspath(path)), out):
            raise FarmInputError(f"{path}: could not package the stage and its assets for --ship-assets")
        with open(out, "rb") as f:
            return f.read()


def connect(address: str):
    """A Dask client for ``address`` -> (client, cluster or None, threads per task or None).

    ``local:N`` starts a LocalCluster of N single-threaded worker processes bound to 127.0.0.1 (dashboard too);
    an address ``tcp://``/``tls://``/… connects to a running scheduler, with Dask's security configuration
    (``distributed.comm.tls.*``) for TLS; anything else is read as a scheduler file."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise FarmInputError("--scheduler needs Dask: pip install 'whitted[farm]' (dask[distributed])") from None
    import logging

    if address.startswith("local:") or address == "local":
        n = address.partition(":")[2] or str(os.cpu_count() or 1)
        if not n.isdigit() or int(n) < 1:
            raise FarmInputError(f"--scheduler {address!r}: expected local:N with N >= 1 workers")
        n = int(n)
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                               dashboard_address="127.0.0.1:0", silence_logs=logging.ERROR)
        return Client(cluster), cluster, max(1, (os.cpu_count() or 1) // n)
    if address.startswith(ADDRESS_SCHEMES):
        if address.startswith("tls://"):
            import dask

            if not dask.config.get("distributed.comm.tls.client.cert", None) and \
                    not dask.config.get("distributed.comm.tls.ca-file", None):
                raise FarmInputError(f"--scheduler {address}: tls:// needs Dask's TLS configuration "
                                     "(distributed.comm.tls.ca-file and client cert/key)")
        try:
            return Client(address, timeout="20s"), None, None
        except OSError as exc:
            raise FarmInputError(f"--scheduler {address}: cannot reach the scheduler ({exc})") from None
    if os.path.isfile(address):
        try:
            return Client(scheduler_file=address, timeout="20s"), None, None
        except (OSError, ValueError) as exc:
            raise FarmInputError(f"--scheduler {address}: cannot use this scheduler file ({exc})") from None
    raise FarmInputError(f"--scheduler {address!r}: expected tcp://HOST:PORT, tls://HOST:PORT, local:N "
                         "or a scheduler file")


def render_on_farm(args, frames, settings: dict, out_path, write) -> int:
    """The CLI's farm path: frames (one task each) or, for a single frame, tiles; returns the exit code.

    ``frames`` are time codes (``[None]`` for the stage's default time); ``out_path(frame)`` names each output;
    ``write(image, path)`` writes an image and its AOVs (atomically) on the client."""
    from tqdm import tqdm

    from tracer.farm import render_frames, render_tiled

    path = os.path.abspath(args.scene)
    assets = package_assets(path) if args.ship_assets else None
    source = UsdSource(path=path, camera=args.camera, width=args.width, height=args.height,
                       purposes=tuple(args.purposes), default_light=not args.no_default_light,
                       complexity=getattr(args, "complexity", "medium"), settings=settings)
    client, cluster, threads = connect(args.scheduler)
    if threads is not None and settings.get("threads") is None:
        source = replace(source, settings=dict(settings, threads=threads))
    quiet = args.quiet
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
            write(image, out_path(frames[0]))
        else:
            bar = None if quiet else tqdm(total=len(frames), unit="frame", desc="whitted farm", leave=False)
            worker_write = WriteFrames(os.path.abspath(args.output), True, tuple(settings.get("aovs", ()))) \
                if args.worker_writes else None
            for res in render_frames(client, source, frames, assets=assets, write=worker_write):
                if res.error is not None:
                    failed += 1
                    print(f"whitted: error: frame {res.frame:g}: {res.error}", file=sys.stderr)
                elif res.image is not None:
                    write(res.image, out_path(res.frame))
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
