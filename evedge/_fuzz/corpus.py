"""Fuzz inputs per target: mutations of real and generated files, and crafted structures.

:func:`cases` yields :class:`Case` objects lazily; each writes its input only
when run (:meth:`Case.materialise`) and removes it afterwards, so a long
campaign needs little disk. Case ``i`` of a target depends only on
``(seed, target, i)``: a failure list can be replayed.
"""

from __future__ import annotations

import io
import shutil
import struct
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import mutate as mu
from .targets import MESH_FORMATS, NATIVE_FORMATS

REPO = Path(__file__).resolve().parents[2]
#: The real recordings beside the repository (not part of it); optional.
REALDATA = REPO.parent / "shared" / "realdata"


@dataclass
class Case:
    """One fuzz input: ``build(folder) -> path`` writes it."""

    case_id: str
    target: str
    mutation: str
    build: Callable[[Path], Path]
    root: Path
    extra: dict = field(default_factory=dict)

    def materialise(self) -> Path:
        self._dir = self.root / self.case_id.replace("/", "_")
        self._dir.mkdir(parents=True, exist_ok=True)
        made = self.build(self._dir)
        if isinstance(made, tuple):  # (path, description known only once built)
            made, self.mutation = made
        return made

    def cleanup(self) -> None:
        shutil.rmtree(self._dir, ignore_errors=True)


# ---------------------------------------------------------------- seed files


def _write_files(d: Path, files: dict) -> None:
    """Write ``files`` (relative path -> bytes) under the folder ``d``, making sub-folders."""
    for rel, content in files.items():
        (d / rel).parent.mkdir(parents=True, exist_ok=True)
        (d / rel).write_bytes(content)


def small_recording(n: int = 2000, seed: int = 0, *, frames: bool = True, truth: bool = True):
    """A 240x180 recording with float frames, edge maps and simulator-like truth."""
    from evedge.events import Frames, Recording, SensorSize, make_events

    rng = np.random.default_rng(seed)
    size = SensorSize(240, 180)
    t = np.sort(rng.integers(0, 500_000, n))
    ev = make_events(rng.integers(0, 240, n), rng.integers(0, 180, n), t, rng.integers(0, 2, n))
    tr = fr = ed = None
    if truth:
        tr = np.empty(n, dtype=[("vx_px_s", "f8"), ("vy_px_s", "f8"), ("nx", "f8"), ("ny", "f8"),
                                ("lifetime_us", "f8"), ("is_signal", "?"), ("t_ns", "i8")])
        for name in ("vx_px_s", "vy_px_s", "nx", "ny"):
            tr[name] = rng.normal(size=n)
        tr["lifetime_us"] = rng.uniform(1e3, 3e4, n)
        tr["is_signal"] = rng.random(n) > 0.1
        tr["t_ns"] = t * 1000 + rng.integers(-500, 500, n)  # the instant in ns, t its rounding to us
    if frames:
        yy, xx = np.mgrid[0:180, 0:240]
        fr = Frames(np.array([0, 200_000, 400_000]),
                    np.stack([((np.sin((xx + 7 * k) / 9.0) * np.cos(yy / 11.0) + 1) / 2).astype(np.float32)
                              for k in range(3)]))
        ed = Frames(np.array([100_000, 300_000]), rng.random((2, 180, 240)) > 0.9)
    return Recording(ev, size, frames=fr, truth=tr, edges=ed, metadata={"scene": "fuzz", "seed": seed})


class Seeds:
    """Seed inputs, built once into ``folder``."""

    def __init__(self, folder: Path, realdata: Path | None = REALDATA):
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.realdata = realdata if realdata is not None and Path(realdata).is_dir() else None
        self._cache: dict = {}

    def _once(self, key, make):
        if key not in self._cache:
            self._cache[key] = make()
        return self._cache[key]

    def ecd_texts(self) -> list[bytes]:
        def make():
            from evedge.io import write_ecd

            out = []
            if self.realdata:
                with open(self.realdata / "slider_depth" / "events_chunk.txt", "rb") as fh:
                    out.append(b"".join(fh.readline() for _ in range(1500)))
            folder = write_ecd(self.folder / "gen_ecd", small_recording(800, 1, frames=False))
            out.append((folder / "events.txt").read_bytes())
            out.append(b"# a comment\n" + out[-1][:2000] + b"\n# trailing comment\n")
            return out

        return self._once("ecd_texts", make)

    def ecd_folders(self) -> list[dict[str, bytes]]:
        """Folders as ``{relative name: content}``."""

        def make():
            from evedge.io import write_ecd

            out = []
            if self.realdata:
                src = self.realdata / "slider_depth"
                lines = (src / "images.txt").read_bytes().split(b"\n")[:3]
                files = {"images.txt": b"\n".join(lines) + b"\n"}
                for line in lines:
                    name = line.split()[1].decode()
                    files[name] = (src / name).read_bytes()
                with open(src / "events_chunk.txt", "rb") as fh:
                    files["events.txt"] = b"".join(fh.readline() for _ in range(1000))
                out.append(files)
            folder = write_ecd(self.folder / "gen_ecd_frames", small_recording(600, 2))
            out.append({p.relative_to(folder).as_posix(): p.read_bytes()
                        for p in sorted(folder.rglob("*")) if p.is_file()})
            return out

        return self._once("ecd_folders", make)

    def mats(self) -> list[bytes]:
        def make():
            import scipy.io

            out = []
            if self.realdata:
                out.append((self.realdata / "rpg_event_lifetime" / "building.mat").read_bytes())
            rec = small_recording(500, 3, frames=False, truth=False)
            ev = rec.events
            m = np.column_stack([ev["x"], ev["y"], np.where(ev["p"], 1, -1), ev["t"]]).astype(np.int32)
            for compress in (True, False):
                buf = io.BytesIO()
                scipy.io.savemat(buf, {"events": m[:40 if not compress else None]}, do_compression=compress)
                out.append(buf.getvalue())
            return out

        return self._once("mats", make)

    def hdf5(self) -> tuple[bytes, str]:
        """An evedge HDF5 file and the digest of the recording it holds."""

        def make():
            from evedge.io import read_hdf5, write_recording

            from .targets import recording_digest

            path = write_recording(self.folder / "seed.h5", small_recording(1500, 4))
            return path.read_bytes(), recording_digest(read_hdf5(path))

        return self._once("hdf5", make)

    def aedat4s(self) -> list[bytes]:
        def make():
            rng = np.random.default_rng(5)
            out = []
            for n_packets in (1, 3):
                packets = []
                t0 = 1_700_000_000_000_000
                for _ in range(n_packets):
                    n = int(rng.integers(1, 60))
                    t = t0 + np.sort(rng.integers(0, 10_000, n))
                    t0 = int(t[-1])
                    packets.append((rng.integers(0, 64, n), rng.integers(0, 48, n), t, rng.integers(0, 2, n)))
                out.append(aedat4_bytes(64, 48, packets))
            return out

        return self._once("aedat4", make)

    def native(self, fmt: str) -> list[bytes]:
        """Files of a registered format: written by its writer, or built (AEDAT 2/3, read only)."""

        def make():
            rec = small_recording(700, 6, frames=False, truth=False)
            if fmt == "aedat2":
                return [aedat2_bytes(rec, davis) for davis in (False, True)]
            if fmt == "aedat3":
                return [aedat3_bytes(rec)]
            from evedge.io import write_events

            path = write_events(self.folder / f"seed.{fmt}", rec, format=fmt)
            return [path.read_bytes()]

        return self._once(f"native_{fmt}", make)

    def detection(self) -> list[bytes]:
        def make():
            from evedge.io.detection import LIFETIME_COLUMNS, Detection, write_detection
            from evedge.events import Frames

            rec = small_recording(600, 7, frames=False, truth=False)
            table = np.zeros(rec.events.size, dtype=list(LIFETIME_COLUMNS))
            table["lifetime_us"] = np.linspace(1e3, 2e4, rec.events.size)
            table["valid"] = table["kept"] = True
            edges = Frames(np.array([100_000, 200_000]), np.random.default_rng(7).random((2, 180, 240)) > 0.9)
            det = Detection(rec.sensor_size, rec.events, table, edges, {"method": "intra", "params": {}})
            return [write_detection(self.folder / "seed_det.h5", det).read_bytes()]

        return self._once("detection", make)

    def meshes(self, fmt: str) -> list[bytes]:
        """A textured-free box and a vertex-coloured sphere, exported by trimesh as ``fmt``."""
        def make():
            import trimesh

            box = trimesh.creation.box(extents=(1.0, 2.0, 0.5))
            ball = trimesh.creation.icosphere(subdivisions=1, radius=0.7)
            ball.visual.vertex_colors = np.tile(np.array([200, 120, 40, 255], np.uint8), (len(ball.vertices), 1))
            return [m.export(file_type=fmt) for m in (box, ball)]
        return [d.encode() if isinstance(d, str) else bytes(d) for d in self._once("mesh_" + fmt, make)]

    def frames_folders(self) -> list[dict[str, bytes]]:
        """Frames folders of ``evedge simulate --frames`` as ``{relative name: content}``, the folder ``images``.

        8-bit grey PNGs with ``timestamps.txt``, 16-bit and colour PNGs, JPEGs,
        and an Event Camera Dataset layout (``images.txt`` beside ``images/``).
        """
        def make():
            import cv2

            frames = _frames_seed()
            times = b"".join(b"%.6f\n" % (k / 200.0) for k in range(len(frames)))
            out = []
            for kind in ("png8", "png16", "pngbgr", "jpg", "ecd"):
                files = {}
                for k, img in enumerate(frames):
                    if kind == "png16":
                        img = img.astype(np.uint16) * 257
                    elif kind == "pngbgr":
                        img = np.stack([img, img[::-1], 255 - img], axis=2)
                    ext = ".jpg" if kind == "jpg" else ".png"
                    ok, enc = cv2.imencode(ext, img)
                    files[f"images/frame_{k:04d}{ext}"] = enc.tobytes()
                if kind == "ecd":
                    files["images.txt"] = b"".join(b"%.6f images/frame_%04d.png\n" % (k / 200.0, k)
                                                   for k in range(len(frames)))
                else:
                    files["images/timestamps.txt"] = times
                out.append(files)
            return out

        return self._once("frames_folders", make)

    def frames_digest(self, k: int) -> str:
        """The digest :func:`~evedge._fuzz.targets.frames_folder` gives for the intact folder ``k``."""
        def make():
            from .targets import frames_folder

            digests = []
            for i, files in enumerate(self.frames_folders()):
                d = self.folder / f"frames_{i}"
                for rel, content in files.items():
                    (d / rel).parent.mkdir(parents=True, exist_ok=True)
                    (d / rel).write_bytes(content)
                digests.append(frames_folder(str(d / "images")).frames_digest)
            return digests

        return self._once("frames_digests", make)[k]

    def videos(self) -> list[tuple[str, bytes]]:
        """Small videos ``(file name, content)``: MJPEG in AVI, MPEG-4 part 2 in MP4, FFV1 in MKV (OpenCV's FFmpeg)."""
        def make():
            import cv2

            out = []
            for fourcc, name in (("MJPG", "clip.avi"), ("mp4v", "clip.mp4"), ("FFV1", "clip.mkv")):
                path = self.folder / name
                writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), 200.0, (32, 24), isColor=False)
                for img in _frames_seed():
                    writer.write(img)
                writer.release()
                out.append((name, path.read_bytes()))
            return out

        return self._once("videos", make)

    def dataset_specs(self) -> list[bytes]:
        return self._once("dataset_specs",
                          lambda: [p.read_bytes() for p in sorted((REPO / "scenes" / "datasets").glob("*.toml"))])

    def scenes(self) -> list[bytes]:
        return self._once("scenes", lambda: [p.read_bytes() for p in sorted((REPO / "scenes").glob("*.toml"))])


def _frames_seed(n: int = 5, width: int = 32, height: int = 24) -> list[np.ndarray]:
    """``n`` 8-bit grey frames of a bright bar moving right (events at every frame interval)."""
    xx = np.arange(width)[None, :]
    return [np.repeat(np.where(np.abs(xx - 6 - 4 * k) < 4, 220, 40).astype(np.uint8), height, axis=0)
            for k in range(n)]


# ---------------------------------------------------------------- AEDAT 4 writer


def _flatbuffer_ioheader(description: str) -> bytes:
    # IOHeader table {compression (absent: None), file_data_position (absent: -1), description}
    text = description.encode()
    body = struct.pack("<I", 20) + b"IOHE" + struct.pack("<HHHHH", 10, 8, 0, 0, 4) + b"\0\0"
    body += struct.pack("<i", 12) + struct.pack("<I", 4) + struct.pack("<I", len(text)) + text + b"\0"
    body += b"\0" * (-len(body) % 4)
    return struct.pack("<I", len(body)) + body


def _flatbuffer_event_packet(stream_id: int, x, y, t, on) -> bytes:
    # size-prefixed EventPacket {elements: [Event{t: i64, x: i16, y: i16, on: bool}]}, 8-aligned structs
    n = len(t)
    body = bytearray(struct.pack("<I", 0) + struct.pack("<I", 16) + b"EVTS" + struct.pack("<HHH", 6, 8, 4) + b"\0\0")
    body += struct.pack("<i", 8) + struct.pack("<I", 4) + struct.pack("<I", n)
    rec = np.zeros(n, dtype=[("t", "<i8"), ("x", "<i2"), ("y", "<i2"), ("on", "u1"), ("pad", "V3")])
    rec["t"], rec["x"], rec["y"], rec["on"] = t, x, y, on
    body += rec.tobytes()
    body[0:4] = struct.pack("<I", len(body) - 4)
    return struct.pack("<II", stream_id, len(body)) + bytes(body)


def aedat4_bytes(width: int, height: int, packets: list[tuple], stream_type: str = "EVTS") -> bytes:
    """An uncompressed AEDAT 4 file with one event stream (id 0); packets are ``(x, y, t, on)`` columns."""
    description = (
        '<dv version="2.0"><node name="outInfo"><node name="0">'
        f'<attr key="typeIdentifier" type="string">{stream_type}</attr><node name="info">'
        f'<attr key="sizeX" type="int">{width}</attr><attr key="sizeY" type="int">{height}</attr>'
        "</node></node></node></dv>"
    )
    data = b"#!AER-DAT4.0\r\n" + _flatbuffer_ioheader(description)
    return data + b"".join(_flatbuffer_event_packet(0, *cols) for cols in packets)


def aedat2_bytes(rec, davis: bool) -> bytes:
    """An AEDAT 2.0 file (jAER): big-endian (address, time) pairs after a ``#`` header."""
    ev = rec.events
    if davis:
        header, address = "# HardwareInterface: DAVIS240C\r\n", (ev["y"].astype(np.uint32) << 22) | \
            (ev["x"].astype(np.uint32) << 12) | (ev["p"].astype(np.uint32) << 11)
    else:
        keep = (ev["x"] < 128) & (ev["y"] < 128)
        ev = ev[keep]
        header, address = "# HardwareInterface: DVS128\r\n", (ev["y"].astype(np.uint32) << 8) | \
            (ev["x"].astype(np.uint32) << 1) | ev["p"].astype(np.uint32)
    raw = np.empty(ev.size, dtype=[("a", ">u4"), ("t", ">i4")])
    raw["a"], raw["t"] = address, ev["t"]
    return b"#!AER-DAT2.0\r\n" + header.encode() + raw.tobytes()


def aedat3_bytes(rec, per_packet: int = 200) -> bytes:
    """An AEDAT 3.1 file (cAER): polarity-event packets (28-byte header, 8-byte events)."""
    data = b"#!AER-DAT3.1\r\n#Format: RAW\r\n#Source 1: DAVIS240C\r\n#!END-HEADER\r\n"
    ev = rec.events
    for start in range(0, ev.size, per_packet):
        chunk = ev[start:start + per_packet]
        body = np.empty(chunk.size, dtype=[("d", "<u4"), ("t", "<i4")])
        body["d"] = (chunk["x"].astype(np.uint32) << 17) | (chunk["y"].astype(np.uint32) << 2) | \
            (chunk["p"].astype(np.uint32) << 1) | 1
        body["t"] = chunk["t"]
        n = chunk.size
        data += np.array([(1, 1, 8, 4, 0, n, n, n)], dtype=[("a", "<i2"), ("b", "<i2"), ("c", "<i4"), ("d", "<i4"),
                                                            ("e", "<i4"), ("f", "<i4"), ("g", "<i4"),
                                                            ("h", "<i4")]).tobytes() + body.tobytes()
    return data


# ---------------------------------------------------------------- crafted inputs


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def crafted_png(rng, width=240, height=180) -> tuple[bytes, str]:
    """PNGs with valid CRCs but lying or odd headers and data."""
    kind = int(rng.integers(0, 7))
    w, h, depth, colour, rows = width, height, 8, 0, height
    if kind == 0:
        w = h = 1 << int(rng.integers(14, 17))  # decompression bomb territory
        rows = 1
    elif kind == 1:
        rows = int(rng.integers(0, height))  # rows missing
    elif kind == 2:
        colour = 2  # RGB
    elif kind == 3:
        depth = 16
    elif kind == 4:
        w, h, rows = width + 1, height, height
    bpp = (3 if colour == 2 else 1) * depth // 8
    raw = b"".join(b"\0" + bytes(rng.integers(0, 256, w * bpp, dtype=np.uint8)) for _ in range(min(rows, h)))
    idat = zlib.compress(raw)
    if kind == 5:
        idat = idat[: len(idat) // 2]  # stream ends early
    ihdr = struct.pack(">IIBBBBB", w, h, depth, colour, 0, 0, 0)
    data = b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", ihdr) + _png_chunk(b"IDAT", idat)
    if kind != 6:
        data += _png_chunk(b"IEND", b"")
    return data, f"png{kind}:{w}x{h}/{depth}bit/c{colour}/{rows}rows"


def crafted_mat(rng) -> tuple[bytes, str]:
    """``.mat`` files with odd structures, or honest headers patched to lie about sizes."""
    import scipy.io

    kind = int(rng.integers(0, 14))
    good = np.array([[1, 2, 1, 10], [3, 4, -1, 20], [5, 6, 1, 30]], dtype=np.int32)
    variables = {
        0: {"events": np.array([[1.0, 2, 1, np.nan]] * 3)},
        1: {"events": good.astype(np.int8)},
        2: {"events": good.astype(np.complex128)},
        3: {"events": np.zeros((2, 3, 4))},
        4: {"events": {"x": good[:, 0], "t": good[:, 3]}},
        5: {"events": np.array([good, "a"], dtype=object)},
        6: {"events": "not numbers"},
        7: {"events": good.astype(bool)},
        8: {"events": np.array([[1, 2, 1, 2**62]], dtype=np.uint64)},
        9: {"events": np.array([[1e300, 2, 1, 3]])},
        10: {"other": good},
    }
    if kind in variables:
        buf = io.BytesIO()
        scipy.io.savemat(buf, variables[kind], do_compression=bool(rng.integers(0, 2)))
        return buf.getvalue(), f"mat_struct{kind}"
    if kind == 11:
        import scipy.sparse

        buf = io.BytesIO()
        scipy.io.savemat(buf, {"events": scipy.sparse.csc_matrix(good.astype(float))})
        return buf.getvalue(), "mat_sparse"
    buf = io.BytesIO()
    compress = kind == 13
    scipy.io.savemat(buf, {"events": good}, do_compression=compress)
    data = bytearray(buf.getvalue())
    value = int(rng.choice([2**31 - 8, 2**30, 2**28, 2**32 - 8]))
    if compress:
        # the miCOMPRESSED element's byte count sits right after the 128-byte header
        data[132:136] = struct.pack("<I", value)
        return bytes(data), f"mat_compressed_size={value}"
    # uncompressed miMATRIX: tag(8) flags(16) dims tag(8) dims(8) ...; patch the dims or the matrix size
    if rng.integers(0, 2):
        data[128 + 8 + 16 + 8: 128 + 8 + 16 + 16] = struct.pack("<ii", value // 4, 4)
        return bytes(data), f"mat_dims={value // 4}x4"
    data[132:136] = struct.pack("<I", value)
    return bytes(data), f"mat_size={value}"


def crafted_aedat4(rng) -> tuple[bytes, str]:
    kind = int(rng.integers(0, 6))
    ok = aedat4_bytes(16, 16, [([1, 2], [3, 4], [10, 20], [1, 0])])
    header_end = len(b"#!AER-DAT4.0\r\n") + 4 + struct.unpack_from("<I", ok, 14)[0]
    if kind == 0:
        size = int(rng.choice([-5, -1, 2**31 - 1, 2**30]))
        return ok[:header_end + 4] + struct.pack("<i", size) + ok[header_end + 8:], f"aedat_packet_size={size}"
    if kind == 1:
        sid = int(rng.choice([-1, 1, 2**31 - 1]))
        return ok[:header_end] + struct.pack("<i", sid) + ok[header_end + 4:], f"aedat_stream_id={sid}"
    if kind == 2:
        size = int(rng.choice([0, 2**31 - 1, 2**32 - 1]))
        return ok[:14] + struct.pack("<I", size) + ok[18:], f"aedat_header_size={size}"
    if kind == 3:
        return aedat4_bytes(16, 16, [([1], [1], [5], [1])], stream_type="FRME"), "aedat_frame_stream_of_events"
    if kind == 4:
        n = int(rng.choice([2**20, 2**28, 2**31 - 1]))
        pkt = bytearray(_flatbuffer_event_packet(0, [1], [1], [5], [1]))
        # elements vector length (after the 8-byte packet header, 4-byte size prefix and table)
        pkt[8 + 4 + 24: 8 + 4 + 28] = struct.pack("<I", n)
        return ok[:header_end] + bytes(pkt), f"aedat_vector_len={n}"
    return aedat4_bytes(int(rng.choice([0, 40000, 2**31 - 1])), 16, [([1], [1], [5], [1])]), "aedat_size"


def crafted_jpeg(rng, width=32, height=24) -> tuple[bytes, str]:
    """A JPEG whose frame header (SOF0) declares another size: huge, zero, or off by one from the others."""
    import cv2

    ok, enc = cv2.imencode(".jpg", _frames_seed(1, width, height)[0])
    data = bytearray(enc.tobytes())
    sof = data.find(b"\xff\xc0")
    h, w = (int(v) for v in rng.choice([[65535, 65535], [65500, 8], [8, 65500], [0, width], [height, 0],
                                        [height, width + 1], [height + 1, width], [30000, 30000]]))
    data[sof + 5: sof + 9] = struct.pack(">HH", h, w)
    return bytes(data), f"jpeg_sof={w}x{h}"


_TIMES = ("nan", "inf", "-inf", "-1", "-1e-3", "0", "1e-300", "1e300", "9e12", "9e9", "9.3e9", "1e19", "1e308", "-9e12", "5e-324",
          "0.0025", "0.005", "1e15", "1e15.001", "", "#", "0.01 0.02", "1,5", "1e-9")


def crafted_timestamps(n: int, rng) -> tuple[bytes, str]:
    """Frame times with odd values: NaN/inf, negative, equal, decreasing, huge, tiny steps, too many or too few."""
    kind = int(rng.integers(0, 5))
    t = [f"{k / 200.0:.6f}" for k in range(n)]
    if kind == 0:
        i = int(rng.integers(0, n))
        t[i] = _TIMES[int(rng.integers(0, len(_TIMES)))]
        what = f"t[{i}]={t[i]}"
    elif kind == 1:
        step = float(rng.choice([1e-300, 1e-12, 1e-9, 1e6, 2.25e9, 2.31e9, 1e12, 3e12, -1.0]))
        start = float(rng.choice([0.0, -1e12, 1e12, 9e12, 1e300]))
        t = [repr(start + k * step) for k in range(n)]
        what = f"start={start:g},step={step:g}"
    elif kind == 2:
        m = int(rng.choice([0, 1, n - 1, n + 1, 10 * n]))
        t = [f"{k / 200.0:.6f}" for k in range(m)]
        what = f"{m}_times"
    elif kind == 3:
        i = int(rng.integers(1, n))
        t[i] = t[i - 1]
        what = f"t[{i}]=t[{i - 1}]"
    else:
        i = int(rng.integers(1, n))
        t[i - 1], t[i] = t[i], t[i - 1]
        what = f"swap{i - 1},{i}"
    return ("\n".join(t) + "\n").encode(), "timestamps:" + what


def crafted_video(data: bytes, rng) -> tuple[bytes, str]:
    """A video whose headers declare another frame size or count: the size pairs (32, 24) of the container and
    codec headers (AVI/BITMAPINFOHEADER int32 LE, MP4 sample entry uint16 BE, JPEG SOF uint16 BE h, w) patched."""
    patterns = [(struct.pack("<ii", 32, 24), "<ii", False), (struct.pack(">HH", 32, 24), ">HH", False),
                (struct.pack(">HH", 24, 32), ">HH", True)]
    hits = [(i, fmt, swap) for pat, fmt, swap in patterns for i in _find_all(data, pat)]
    if not hits or rng.random() < 0.2:
        # a count or size field somewhere in the first kilobyte (frame counts, chunk sizes, ...)
        i = int(rng.integers(0, max(1, min(len(data), 1024) // 4))) * 4
        value = int(rng.choice([0, 1, 2**16, 2**24, 2**31 - 1, 2**32 - 1]))
        return data[:i] + struct.pack("<I", value) + data[i + 4:], f"video_u32@{i}={value}"
    i, fmt, swap = hits[int(rng.integers(0, len(hits)))]
    big = 65535 if fmt == ">HH" else 2**31 - 1
    w, h = (int(v) for v in rng.choice([[big, big], [big, 24], [32, big], [0, 24], [32, 0], [33, 24], [30000, 30000],
                                        [16384, 16384]]))
    if fmt == "<ii" and rng.random() < 0.3:
        w, h = -w, -h
    field = struct.pack(fmt, *((h, w) if swap else (w, h)))
    return data[:i] + field + data[i + len(field):], f"video_size@{i}={w}x{h}"


def _find_all(data: bytes, pattern: bytes) -> list[int]:
    out, i = [], data.find(pattern)
    while i >= 0 and len(out) < 64:
        out.append(i)
        i = data.find(pattern, i + 1)
    return out


SCENE_KEYS = ("duration_s", "frame_rate_hz", "min_step_s", "min_rate_hz", "noise_rate_hz", "width", "height",
              "lambda_", "refractory_us", "speed_px_s", "jitter_us", "count", "period_px", "radius_px")
DATASET_KEYS = ("count", "seed", "duration_s", "frame_rate_hz", "speed_px_s", "noise_rate_hz", "sensor",
                "shape_count", "period_px", "threshold", "refractory_us", "contrast")


def crafted_scene(seed_text: bytes, rng, keys=SCENE_KEYS) -> tuple[bytes, str]:
    """Scene (or dataset spec) TOML with extreme values for keys that set work or memory."""
    values = ("1e300", "1e-300", str(2**63), str(10**400), "0", "-1", "nan", "inf", "1e6", "9e12", "9e9", "9.3e9", "32767",
              "100000", "1e-9", '"30000x30000"', "{ uniform = [0, 1e300] }", "{ choice = [] }",
              "{ log_uniform = [-1, 5] }", "{ integers = [5, 1] }", '"x"', "[1, 2]")
    key = keys[int(rng.integers(0, len(keys)))]
    value = values[int(rng.integers(0, len(values)))]
    text = seed_text
    lines = text.split(b"\n")
    hits = [i for i, line in enumerate(lines) if line.strip().startswith(key.encode() + b" ")
            or line.strip().startswith(key.encode() + b"=")]
    if hits:
        i = hits[int(rng.integers(0, len(hits)))]
        lines[i] = key.encode() + b" = " + value.encode()
    else:
        # put it in the first table so that it reaches a validator (or the unknown-key check)
        first = next((i for i, line in enumerate(lines) if line.startswith(b"[")), len(lines) - 1)
        lines.insert(first + 1, key.encode() + b" = " + value.encode())
    return b"\n".join(lines), f"scene_{key}={value}"


# ---------------------------------------------------------------- HDF5


def crafted_hdf5(seed_path: Path, out: Path, rng, kind: int | None = None) -> str:
    """Copy ``seed_path`` to ``out`` and change its structure with h5py; returns the change."""
    import h5py

    shutil.copyfile(seed_path, out)
    kind = int(rng.integers(0, 24)) if kind is None else kind
    with h5py.File(out, "r+") as f:
        ev = f["events"]

        def replace(group, name, **kwargs):
            del group[name]
            group.create_dataset(name, **kwargs)

        if kind == 0:
            n = int(rng.choice([2**31, 2**33, 2**40]))
            for name, dt in (("x", "i2"), ("y", "i2"), ("t", "i8"), ("p", "?")):
                replace(ev, name, shape=(n,), dtype=dt, chunks=(1 << 16,), compression="gzip")
            what = f"rows={n}"
        elif kind == 1:
            n = int(rng.choice([10**5, 10**7]))
            replace(f["frames"], "images", shape=(n, 180, 240), dtype="f4", chunks=(1, 180, 240))
            replace(f["frames"], "t_us", data=np.arange(n))
            what = f"frames={n}"
        elif kind == 2:
            del ev["x"]
            ev["x"] = h5py.SoftLink("/events/x")
            what = "softlink_self"
        elif kind == 3:
            del f["events"]
            f["events"] = h5py.SoftLink("/events")
            what = "softlink_group_self"
        elif kind == 4:
            f["a"] = h5py.SoftLink("/b")
            f["b"] = h5py.SoftLink("/a")
            del ev["t"]
            ev["t"] = h5py.SoftLink("/a")
            what = "softlink_loop"
        elif kind == 5:
            del ev["x"]
            ev["x"] = h5py.ExternalLink(str(seed_path), "/events/x")
            what = "external_link"
        elif kind == 6:
            replace(ev, "t", data=np.array([b"1"] * ev["x"].shape[0]))
            what = "t_strings"
        elif kind == 7:
            t = ev["t"][()].astype(float)
            t[int(rng.integers(0, t.size))] = np.nan
            replace(ev, "t", data=t)
            what = "t_float_nan"
        elif kind == 8:
            img = f["frames/images"][()]
            img.flat[int(rng.integers(0, img.size))] = float(rng.choice([np.nan, np.inf, -0.5, 2.0]))
            replace(f["frames"], "images", data=img)
            what = "frames_value"
        elif kind == 9:
            replace(f["frames"], "images", data=np.full((3, 180, 240), b"x"))
            what = "frames_strings"
        elif kind == 10:
            replace(f["frames"], "t_us", data=np.array([0.0, np.nan, 1.0]))
            what = "frames_t_nan"
        elif kind == 11:
            replace(f["edges"], "images", data=f["edges/images"][()].astype(np.uint8) * 3)
            what = "edges_int"
        elif kind == 12:
            lt = f["truth/lifetime_us"][()]
            lt[int(rng.integers(0, lt.size))] = float(rng.choice([np.nan, -1.0, 0.0]))
            replace(f["truth"], "lifetime_us", data=lt)
            what = "truth_value"
        elif kind == 13:
            replace(ev, "x", data=np.int16(3))
            what = "scalar_x"
        elif kind == 14:
            del ev["y"]
            ev.create_group("y")
            what = "group_y"
        elif kind == 15:
            name = str(rng.choice(["sensor_width", "sensor_height"]))
            options = [np.int64(2**40), np.int64(-1), np.int64(0), 1.5, "240", np.array([240, 1])]
            value = options[int(rng.integers(0, len(options)))]
            f.attrs[name] = value
            what = f"attr_{name}={value!r}"
        elif kind == 16:
            f.attrs["metadata"] = str(rng.choice(["not json", "[1, 2]", "{" * 100_000, '"x"']))
            what = "metadata"
        elif kind == 17:
            f.attrs["format_version"] = int(rng.choice([0, 2, 99, -1]))
            what = "format_version"
        elif kind == 18:
            ev.create_dataset("extra", data=np.arange(3))
            what = "extra_dataset"
        elif kind == 19:
            replace(ev, "p", data=ev["p"][()].astype(np.int8) * 2)
            what = "p_int"
        elif kind == 20:
            layout = h5py.VirtualLayout(shape=(ev["x"].shape[0],), dtype="i2")
            layout[:] = h5py.VirtualSource("/etc/does-not-exist.h5", "x", shape=(ev["x"].shape[0],))
            del ev["x"]
            ev.create_virtual_dataset("x", layout, fillvalue=0)
            what = "virtual_dataset"
        elif kind == 21:
            for name in ("x", "y", "t", "p"):
                data = ev[name][()]
                replace(ev, name, data=data[: data.size // 2])
            what = "events_halved"
        elif kind == 22:
            t = ev["t"][()]
            t[-1] = np.iinfo(np.int64).max
            replace(ev, "t", data=t)
            what = "t_int64_max"
        else:
            del f["truth/is_signal"]
            what = "truth_field_missing"
        declared = []
        f.visititems(lambda name, obj: declared.append(obj.size * obj.dtype.itemsize)
                     if isinstance(obj, h5py.Dataset) and obj.shape is not None and not obj.is_virtual else None)
        # sealing reads every dataset: only for files whose declared sizes are honest and small
        reseal = bool(rng.integers(0, 2)) and sum(declared) < 2**26 and kind not in (0, 1, 20)
        if reseal:
            seal = _sealer()
            if seal is not None:
                try:
                    seal(f)
                    what += "+resealed"
                except Exception:  # noqa: BLE001 - a structure too broken to seal is still a test input
                    what += "+unsealable"
    return f"crafted:{what}"


def _sealer():
    """The function that stores the project's checksums in an open file, when the format has one."""
    try:
        from evedge.io.hdf5 import seal
    except ImportError:
        return None
    return seal


# ---------------------------------------------------------------- per target


def _write(folder: Path, name: str, data: bytes) -> Path:
    path = folder / name
    path.write_bytes(data)
    return path


def cases(target: str, n: int, seed: int, root: Path, seeds: Seeds) -> Iterator[Case]:
    """Yield ``n`` cases for ``target`` (a key of :data:`evedge._fuzz.targets.TARGETS`)."""
    for i in range(n):
        rng = np.random.default_rng([seed, sum(target.encode()), i])
        case_id = f"{target}/{seed}/{i}"
        yield _one(target, case_id, rng, root, seeds)


def _one(target: str, case_id: str, rng, root: Path, seeds: Seeds) -> Case:
    crafted = rng.random() < 0.3
    extra: dict = {}
    if target == "ecd_text":
        texts = seeds.ecd_texts()
        data, what = mu.mutate(texts[int(rng.integers(0, len(texts)))], rng, mu.TEXT_MUTATORS)
        return Case(case_id, target, what, lambda d: _write(d, "events.txt", data), root)
    if target == "ecd_folder":
        base = dict(seeds.ecd_folders()[int(rng.integers(0, len(seeds.ecd_folders())))])
        names = sorted(base)
        name = names[int(rng.integers(0, len(names)))]
        if name.endswith(".png"):
            if crafted:
                base[name], what = crafted_png(rng)
            else:
                base[name], what = mu.mutate(base[name], rng, mu.BYTE_MUTATORS, 2)
        elif crafted and rng.random() < 0.5:
            what = "remove"
            del base[name]
        else:
            base[name], what = mu.mutate(base[name], rng, mu.TEXT_MUTATORS)

        def build(d: Path, files=base) -> Path:
            _write_files(d, files)
            return d

        return Case(case_id, target, f"{name}:{what}", build, root)
    if target == "mat":
        if crafted:
            data, what = crafted_mat(rng)
        else:
            mats = seeds.mats()
            data, what = mu.mutate(mats[int(rng.integers(0, len(mats)))], rng, mu.BYTE_MUTATORS, 2)
        return Case(case_id, target, what, lambda d: _write(d, "events.mat", data), root)
    if target in ("hdf5", "hdf5_stream", "hdf5_any"):
        data, digest = seeds.hdf5()
        if crafted:
            seed_path = seeds.folder / "seed.h5"
            sub = np.random.default_rng(rng.integers(0, 2**63))

            def build(d: Path) -> Path:
                what = crafted_hdf5(seed_path, d / "rec.h5", np.random.default_rng(sub.integers(0, 2**63)))
                return d / "rec.h5", what

            return Case(case_id, target, "crafted", build, root)
        new, what = mu.mutate(data, rng, mu.BYTE_MUTATORS, 2)
        extra = {"expect_digest": digest}
        return Case(case_id, target, what, lambda d: _write(d, "rec.h5", new), root, extra)
    if target == "aedat4":
        if crafted:
            data, what = crafted_aedat4(rng)
        else:
            files = seeds.aedat4s()
            data, what = mu.mutate(files[int(rng.integers(0, len(files)))], rng, mu.BYTE_MUTATORS, 2)
        return Case(case_id, target, what, lambda d: _write(d, "rec.aedat4", data), root)
    if target == "scene":
        texts = seeds.scenes()
        text = texts[int(rng.integers(0, len(texts)))]
        if crafted or rng.random() < 0.3:
            data, what = crafted_scene(text, rng)
        else:
            data, what = mu.mutate(text, rng, mu.TEXT_MUTATORS)
        return Case(case_id, target, what, lambda d: _write(d, "scene.toml", data), root)
    if target in NATIVE_FORMATS or target == "detection":
        files = seeds.native(target) if target != "detection" else seeds.detection()
        base = files[int(rng.integers(0, len(files)))]
        if crafted:
            # the text header (prophesee '%', AEDAT '#') or the binary header right after it
            head, tail = base[:400], base[400:]
            head, what = mu.mutate(head, rng, (mu.replace_number, mu.overwrite_int, mu.insert_line, mu.delete_line))
            data, what = head + tail, "header:" + what
        else:
            data, what = mu.mutate(base, rng, mu.BYTE_MUTATORS, 2)
        suffix = {"evt3": ".raw", "evt2": ".raw", "dat": ".dat", "es": ".es", "aedat2": ".aedat",
                  "aedat3": ".aedat", "detection": ".h5"}[target]
        return Case(case_id, target, what, lambda d: _write(d, "rec" + suffix, data), root)
    if target.startswith("mesh_") and target[5:] in MESH_FORMATS:
        fmt = target[5:]
        files = seeds.meshes(fmt)
        base = files[int(rng.integers(0, len(files)))]
        if fmt == "obj" or (fmt == "ply" and crafted):  # OBJ is text; a PLY header is text too
            data, what = mu.mutate(base, rng, mu.TEXT_MUTATORS)
        else:
            data, what = mu.mutate(base, rng, mu.BYTE_MUTATORS, 2)
        return Case(case_id, target, what, lambda d: _write(d, "mesh." + fmt, data), root)
    if target == "frames":
        folders = seeds.frames_folders()
        k = int(rng.integers(0, len(folders)))
        base = dict(folders[k])
        names = sorted(base)
        name = names[int(rng.integers(0, len(names)))]
        n_frames = sum(1 for rel in base if rel.startswith("images/frame_"))
        expect = None
        if name.endswith((".png", ".jpg")):
            if crafted:
                base[name], what = crafted_png(rng, 32, 24) if name.endswith(".png") else crafted_jpeg(rng)
            else:
                base[name], what = mu.mutate(base[name], rng, mu.BYTE_MUTATORS, 2)
                # PNG has checksums and a length: a damaged one is refused or decodes to the same pixels;
                # JPEG has neither, only its end marker: a cut or zeroed tail is refused
                if name.endswith(".png") or what.split("+")[-1].startswith(("truncate", "zero_tail")) \
                        and what.count("+") == 0:
                    expect = seeds.frames_digest(k)
        elif crafted and rng.random() < 0.3:
            what = "remove"
            del base[name]
        elif crafted and name.endswith("timestamps.txt"):
            base[name], what = crafted_timestamps(n_frames, rng)
        else:
            base[name], what = mu.mutate(base[name], rng, mu.TEXT_MUTATORS)

        def build(d: Path, files=base) -> Path:
            _write_files(d, files)
            (d / "images").mkdir(exist_ok=True)
            return d / "images"

        return Case(case_id, target, f"{name}:{what}", build, root, {"expect_digest": expect} if expect else {})
    if target == "video":
        videos = seeds.videos()
        name, base = videos[int(rng.integers(0, len(videos)))]
        times = None
        if rng.random() < 0.25:
            times, what = crafted_timestamps(5, rng)
        elif crafted:
            data, what = crafted_video(base, rng)
        else:
            data, what = mu.mutate(base, rng, mu.BYTE_MUTATORS, 2)
        data = base if times is not None else data

        def build(d: Path) -> Path:
            if times is not None:
                _write(d, "timestamps.txt", times)
            return _write(d, name, data)

        return Case(case_id, target, f"{name}:{what}", build, root,
                    {"also_named": ["timestamps.txt"]} if times is not None else {})
    if target == "dataset_spec":
        texts = seeds.dataset_specs()
        text = texts[int(rng.integers(0, len(texts)))]
        if crafted or rng.random() < 0.3:
            data, what = crafted_scene(text, rng, DATASET_KEYS)
        else:
            data, what = mu.mutate(text, rng, mu.TEXT_MUTATORS)
        return Case(case_id, target, what, lambda d: _write(d, "dataset.toml", data), root)
    raise KeyError(f"no corpus for target {target!r}")
