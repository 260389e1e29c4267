"""User meshes (OBJ, GLB, PLY, ... via trimesh) with textures or vertex colours, rendered by pyrender.

A :class:`SceneMesh` is a triangle mesh in the world frame whose surface carries a linear
intensity in [0, 1]: a grey texture image with per-vertex texture coordinates, per-corner
intensities (vertex colours, or one flat value per face), or both multiplied.
:class:`RasterMeshRenderer` draws them offscreen (pyrender, EGL, Mesa llvmpipe) unlit (pyrender's
FLAT mode: the output is the base colour times the texture times the vertex colour, with no
lighting and no sRGB conversion), so the rendered value *is* the linear intensity, at ``s``
times the resolution with 4x multisampling (Mesa llvmpipe's maximum, ``GL_MAX_SAMPLES = 4``); a
pixel is the mean of its ``s x s`` resolved samples (OpenCV ``INTER_AREA``, an exact box
filter at an integer factor). The default ``s = 2`` (16 samples per pixel) is the fastest
setting within the tested tolerance against the exact box renderer (see
``tests/sim/test_mesh.py`` and ``benchmarks/bench_render3d.py``); ``s = 3`` (36 samples) is
about twice as accurate at edges at about half the speed. Texture and colour channels are 8 bits:
values are quantised to 1/255 before the average.

Per-event truth needs no rendering: :meth:`RasterMeshRenderer.flow_at` casts the event's pixel
ray at the event's time against the triangles (numba, exact), and the motion field follows from
that depth and the camera's motion, as for the box renderer.

Procedural textures (:func:`procedural_texture`: checker, stripes, smooth noise) are generated
at load time: nothing is downloaded.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._gl import ZNEAR_M, _grey_renderer_class, _import_pyrender, _offscreen, _PinholeRenderer
from ._motion_field import image_speed_bound, motion_field
from ._raytri import _first_hit_depth_kernel
from .trajectory import _finite, rotation_from_rpy

__all__ = ["SceneMesh", "RasterMeshRenderer", "procedural_texture", "load_mesh_file", "primitive_mesh",
           "box_mesh", "scene_meshes"]


def _luminance(rgb: np.ndarray) -> np.ndarray:
    """Grey value of 8-bit or float RGB(A) colours in [0, 1] (Rec. 709 weights; values taken as linear)."""
    rgb = np.asarray(rgb, dtype=np.float64)
    if rgb.max(initial=0.0) > 1.0:
        rgb = rgb / 255.0
    if rgb.ndim >= 1 and rgb.shape[-1] >= 3:
        return np.clip(rgb[..., 0] * 0.2126 + rgb[..., 1] * 0.7152 + rgb[..., 2] * 0.0722, 0.0, 1.0)
    return np.clip(rgb[..., 0] if rgb.shape[-1:] == (1,) else rgb, 0.0, 1.0)


@dataclass(frozen=True)
class SceneMesh:
    """A triangle mesh in the world frame with a linear intensity on its surface.

    Parameters
    ----------
    vertices_m : (V, 3) float
        World coordinates (OpenCV axes), metres.
    faces : (F, 3) int
        Vertex indices of the triangles.
    corner_intensity : (F, 3) float or None
        Intensity in [0, 1] at each triangle corner (vertex colours, or a flat value per face),
        interpolated across the triangle; None for 1.
    uv : (V, 2) float or None
        Texture coordinates (with ``texture``).
    texture : (H, W) float or None
        Grey texture in [0, 1] (row 0 at the top, as images; ``v = 1`` samples it).

    Examples
    --------
    >>> m = box_mesh((0, 0, 4), (1, 1, 1), (0.5,) * 6)
    >>> m.faces.shape, float(m.corner_intensity.max())
    ((12, 3), 0.5)
    """

    vertices_m: np.ndarray
    faces: np.ndarray
    corner_intensity: np.ndarray | None = None
    uv: np.ndarray | None = None
    texture: np.ndarray | None = None

    def __post_init__(self):
        v = np.asarray(self.vertices_m, dtype=np.float64)
        f = np.asarray(self.faces)
        if v.ndim != 2 or v.shape[1] != 3 or not np.all(np.isfinite(v)):
            raise ValueError(f"SceneMesh.vertices_m must be finite (V, 3), got shape {v.shape}")
        if f.ndim != 2 or f.shape[1] != 3 or f.shape[0] == 0 or f.dtype.kind not in "iu":
            raise ValueError(f"SceneMesh.faces must be (F, 3) integers with F > 0, got {f.shape} {f.dtype}")
        if f.min() < 0 or f.max() >= v.shape[0]:
            raise ValueError(f"SceneMesh.faces index vertices outside [0, {v.shape[0]})")
        object.__setattr__(self, "vertices_m", v)
        object.__setattr__(self, "faces", f.astype(np.int64))
        if self.corner_intensity is not None:
            c = np.asarray(self.corner_intensity, dtype=np.float64)
            if c.shape != f.shape or not np.all((c >= 0) & (c <= 1)):
                raise ValueError(f"SceneMesh.corner_intensity must be {f.shape} values in [0, 1], got {c.shape}")
            object.__setattr__(self, "corner_intensity", c)
        if (self.uv is None) != (self.texture is None):
            raise ValueError("SceneMesh: give both uv and texture, or neither")
        if self.texture is not None:
            uv = np.asarray(self.uv, dtype=np.float64)
            tex = np.asarray(self.texture, dtype=np.float64)
            if uv.shape != (v.shape[0], 2) or not np.all(np.isfinite(uv)):
                raise ValueError(f"SceneMesh.uv must be finite ({v.shape[0]}, 2), got {uv.shape}")
            if tex.ndim != 2 or min(tex.shape) < 1 or not np.all((tex >= 0) & (tex <= 1)):
                raise ValueError(f"SceneMesh.texture must be a 2-D image in [0, 1], got shape {tex.shape}")
            object.__setattr__(self, "uv", uv)
            object.__setattr__(self, "texture", tex)

    def transformed(self, rotation: np.ndarray, translation_m, scale: float = 1.0) -> "SceneMesh":
        """This mesh scaled, rotated and moved: ``x -> R (s x) + t``."""
        v = (scale * self.vertices_m) @ np.asarray(rotation, dtype=np.float64).T + np.asarray(translation_m)
        return SceneMesh(v, self.faces, self.corner_intensity, self.uv, self.texture)


def procedural_texture(kind: str, cells: int = 8, dark: float = 0.2, light: float = 0.8,
                       resolution_px: int = 512, seed: int = 0) -> np.ndarray:
    """A square grey texture (resolution_px, resolution_px) in [dark, light], generated (not downloaded).

    Parameters
    ----------
    kind : {"checker", "stripes", "noise"}
        ``checker``: ``cells x cells`` squares; ``stripes``: ``cells`` vertical stripe pairs;
        ``noise``: smooth value noise on a ``cells x cells`` lattice (bicubic interpolation of
        uniform values drawn from ``seed``).
    cells : int
        Pattern frequency across the texture (>= 1).
    dark, light : float
        Intensity range, in [0, 1].
    resolution_px : int
        Texture size.
    seed : int
        For ``noise``.

    Examples
    --------
    >>> tex = procedural_texture("checker", cells=2, resolution_px=4)
    >>> tex.tolist()
    [[0.2, 0.2, 0.8, 0.8], [0.2, 0.2, 0.8, 0.8], [0.8, 0.8, 0.2, 0.2], [0.8, 0.8, 0.2, 0.2]]
    """
    n = int(resolution_px)
    if cells < 1 or n < 2:
        raise ValueError(f"procedural_texture: cells >= 1 and resolution_px >= 2 needed, got {cells}, {n}")
    if not (0.0 <= dark <= 1.0 and 0.0 <= light <= 1.0):
        raise ValueError(f"procedural_texture: dark and light must lie in [0, 1], got {dark}, {light}")
    s = (np.arange(n) + 0.5) / n
    if kind == "checker":
        a = np.floor(s * cells).astype(np.int64)
        mask = (a[:, None] + a[None, :]) % 2 == 1
        return np.where(mask, light, dark)
    if kind == "stripes":
        mask = np.floor(s * 2 * cells).astype(np.int64) % 2 == 1
        return np.where(np.broadcast_to(mask[None, :], (n, n)), light, dark)
    if kind == "noise":
        from scipy.ndimage import map_coordinates

        rng = np.random.default_rng(seed)
        lattice = rng.uniform(0.0, 1.0, (cells + 3, cells + 3))
        g = s * cells + 1.0
        yy, xx = np.meshgrid(g, g, indexing="ij")
        values = map_coordinates(lattice, [yy, xx], order=3, mode="nearest")
        values = (values - values.min()) / max(values.max() - values.min(), 1e-12)
        return dark + (light - dark) * values
    raise ValueError(f"procedural_texture: kind must be 'checker', 'stripes' or 'noise', got {kind!r}")


def _quad_faces(count: int) -> np.ndarray:
    base = 4 * np.arange(count)[:, None]
    return np.concatenate([base + [0, 1, 2], base + [0, 2, 3]], axis=1).reshape(-1, 3)


def box_mesh(center_m, size_m, face_intensities, texture: np.ndarray | None = None) -> SceneMesh:
    """An axis-aligned box as 12 triangles, one flat intensity per face (order -x, +x, -y, +y, -z, +z).

    With ``texture``, each face carries the whole texture (times its intensity).

    Examples
    --------
    >>> box_mesh((0, 0, 4), (1, 1, 1), (0.1, 0.2, 0.3, 0.4, 0.5, 0.6)).corner_intensity[8:10, 0].tolist()
    [0.5, 0.5]
    """
    from .boxes import Box3D, box_faces

    box = Box3D(center_m, size_m, face_intensities)
    quads, values = [], []
    for (_, _, corners), value in zip(box_faces(box), box.face_intensities):
        quads.append(corners)
        values.append(value)
    vertices = np.concatenate(quads)
    faces = _quad_faces(6)
    corner = np.repeat(np.repeat(np.asarray(values), 2), 3).reshape(-1, 3)
    uv = np.tile([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]], (6, 1)) if texture is not None else None
    return SceneMesh(vertices, faces, corner, uv, texture)


def primitive_mesh(kind: str, size_m=(1.0, 1.0, 1.0), intensity: float | None = None,
                   texture: np.ndarray | None = None) -> SceneMesh:
    """A mesh primitive centred at the origin (trimesh), with a flat intensity or a texture.

    Parameters
    ----------
    kind : {"box", "plane", "sphere", "cylinder"}
        ``box``: extents ``size_m``, the texture on every face; ``plane``: ``size_m[0] x size_m[1]``
        in the x-y plane (its normal along z), the texture once across it; ``sphere``: an
        icosphere (3 subdivisions) of diameters ``size_m`` (an ellipsoid); ``cylinder``: axis
        along y, height ``size_m[1]``, diameters ``size_m[0]`` (x) and ``size_m[2]`` (z), 48 sides.
    size_m : 3 floats
    intensity : float or None
        Flat intensity in [0, 1] (None: 1), multiplied by the texture.
    texture : (H, W) array or None
        Grey texture in [0, 1], e.g. from :func:`procedural_texture`.

    Returns
    -------
    SceneMesh

    Notes
    -----
    Sphere and cylinder carry a texture by sampling it per triangle at the triangle centre's
    (azimuth, height) coordinates (a flat intensity per face), so their texture edges follow
    the triangulation.

    Examples
    --------
    >>> primitive_mesh("sphere", (1.0, 1.0, 1.0), 0.5).faces.shape
    (1280, 3)
    """
    import trimesh

    value = 1.0 if intensity is None else float(intensity)
    size = np.asarray(size_m, dtype=np.float64)
    if kind == "box":
        return box_mesh((0.0, 0.0, 0.0), size, (value,) * 6, texture)
    if kind == "plane":
        hx, hy = size[0] / 2, size[1] / 2
        vertices = np.array([[-hx, -hy, 0.0], [hx, -hy, 0.0], [hx, hy, 0.0], [-hx, hy, 0.0]])
        uv = np.array([[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]]) if texture is not None else None
        return SceneMesh(vertices, _quad_faces(1), np.full((2, 3), value), uv, texture)
    if kind == "sphere":
        tm = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
        tm.apply_scale(size)
    elif kind == "cylinder":
        tm = trimesh.creation.cylinder(radius=0.5, height=1.0, sections=48)
        tm.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [1, 0, 0]))  # axis along y
        tm.apply_scale(size)
    else:
        raise ValueError(f"primitive_mesh: kind must be one of box, plane, sphere, cylinder, got {kind!r}")
    vertices, faces = np.asarray(tm.vertices, dtype=np.float64), np.asarray(tm.faces, dtype=np.int64)
    corner = np.full(faces.shape, value)
    if texture is not None:
        centres = vertices[faces].mean(axis=1)
        az = (np.arctan2(centres[:, 0], centres[:, 2]) / (2 * math.pi)) % 1.0
        h = np.clip(0.5 - centres[:, 1] / size[1], 0.0, 1.0 - 1e-12)
        rows = (h * texture.shape[0]).astype(np.int64)
        cols = np.minimum((az * texture.shape[1]).astype(np.int64), texture.shape[1] - 1)
        corner = corner * texture[rows, cols][:, None]
    return SceneMesh(vertices, faces, corner)


def load_mesh_file(path) -> list[SceneMesh]:
    """Meshes of a file read by trimesh (OBJ, GLB/glTF, PLY, STL, OFF), in the file's own frame.

    Textures (``TextureVisuals`` with an image) become grey textures, vertex or face colours
    per-corner intensities (luminance of the colour, its values taken as linear); a mesh with
    neither is white (1). Scene graphs are flattened with their transforms.

    Raises
    ------
    ValueError
        The file cannot be read or holds no triangles (the message names it).

    Examples
    --------
    >>> import tempfile, trimesh
    >>> path = tempfile.mkdtemp() + "/box.ply"
    >>> _ = trimesh.creation.box((1, 1, 1)).export(path)
    >>> [m.faces.shape for m in load_mesh_file(path)]
    [(12, 3)]
    """
    import trimesh

    path = Path(path)
    try:
        loaded = trimesh.load(str(path), force="scene")
    except Exception as exc:  # trimesh raises many types on bad files
        raise ValueError(f"{path}: cannot read mesh: {type(exc).__name__}: {exc}") from None
    out = []
    for name in loaded.graph.nodes_geometry:
        try:  # a damaged file can load and still hold indices past its arrays (trimesh checks them lazily)
            mesh = _scene_mesh_of(loaded, name, trimesh)
        except Exception as exc:
            raise ValueError(f"{path}: cannot read mesh {name!r}: {type(exc).__name__}: {exc}") from None
        if mesh is not None:
            out.append(mesh)
    if not out:
        raise ValueError(f"{path}: no triangle mesh in the file")
    return out


def _scene_mesh_of(loaded, name, trimesh) -> SceneMesh | None:
    """The :class:`SceneMesh` of node ``name`` of a loaded trimesh scene (None: no triangles)."""
    transform, geometry_name = loaded.graph[name]
    tm = loaded.geometry[geometry_name]
    if not isinstance(tm, trimesh.Trimesh) or len(tm.faces) == 0:
        return None
    tm = tm.copy()
    tm.apply_transform(transform)
    vertices, faces = np.asarray(tm.vertices, dtype=np.float64), np.asarray(tm.faces, dtype=np.int64)
    visual = tm.visual
    corner, uv, texture = None, None, None
    if visual.kind == "texture" and getattr(visual, "uv", None) is not None:
        material = visual.material
        image = getattr(material, "image", None)
        if image is None:
            image = getattr(material, "baseColorTexture", None)
        factor = getattr(material, "baseColorFactor", None)
        if image is not None:
            texture = _luminance(np.asarray(image.convert("RGB")))
            uv = np.asarray(visual.uv, dtype=np.float64)
        if factor is not None:
            corner = np.full(faces.shape, float(_luminance(np.asarray(factor, dtype=np.float64)[None, :3])[0]))
    elif visual.kind == "vertex":
        corner = _luminance(np.asarray(visual.vertex_colors))[faces]
    elif visual.kind == "face":
        corner = np.repeat(_luminance(np.asarray(visual.face_colors))[:, None], 3, axis=1)
    return SceneMesh(vertices, faces, corner, uv, texture)


def scene_meshes(boxes, meshes, source: str = "<scene>") -> list[SceneMesh]:
    """The :class:`SceneMesh` list of a mesh scene's ``[[boxes]]`` and ``[[meshes]]`` entries (parsed).

    ``boxes`` are :class:`~evedge.sim.boxes.Box3D` keyword dicts, ``meshes`` the entries of
    :func:`evedge.sim.scene3d.parse_mesh`; file errors name ``source`` and the key.

    Examples
    --------
    >>> m = {"primitive": "plane", "size_m": (2.0, 2.0, 1.0), "intensity": 0.3, "texture": None,
    ...      "position_m": (0.0, 0.0, 3.0), "rotation_rpy_rad": (0.0, 0.0, 0.0), "scale": 1.0}
    >>> [float(p.vertices_m[:, 2].max()) for p in scene_meshes([], [m])]
    [3.0]
    """
    out = [box_mesh(b["center_m"], b["size_m"], b["face_intensities"]) for b in boxes]
    for k, m in enumerate(meshes):
        tex = m.get("texture")
        texture = procedural_texture(**tex) if tex else None
        if "file" in m:
            try:
                parts = load_mesh_file(m["file"])
            except ValueError as exc:
                raise ValueError(f"{source}: key 'meshes[{k}].file': {exc}") from None
            if texture is not None or m.get("intensity") is not None:
                value = 1.0 if m.get("intensity") is None else m["intensity"]
                parts = [SceneMesh(p.vertices_m, p.faces, np.full(p.faces.shape, value), p.uv, p.texture)
                         for p in parts]
        else:
            parts = [primitive_mesh(m["primitive"], m["size_m"], m.get("intensity"), texture)]
        rot = rotation_from_rpy(*m["rotation_rpy_rad"])
        out += [p.transformed(rot, m["position_m"], m["scale"]) for p in parts]
    return out


class RasterMeshRenderer(_PinholeRenderer):
    """Render intensity, depth, motion field and edges of textured meshes through pyrender.

    Parameters
    ----------
    width, height : int
        Image size in pixels.
    fx, fy, cx, cy : float
        Pinhole intrinsics (OpenCV convention: pixel centres at integer coordinates).
    meshes : sequence of SceneMesh
        The static scene, world frame.
    trajectory : CameraTrajectory or KeyframeTrajectory
        The camera motion.
    background : float, default 0.5
        Linear intensity where nothing is seen.
    supersample : int, default 2
        ``s >= 1``: the scene is drawn at ``s`` times the resolution and each pixel is the mean
        of its ``s x s`` (multisample-resolved) samples. 2 (with 4x MSAA: 16 samples per pixel)
        meets the tested tolerance against the exact renderer on flat boxes (edge pixels: mean
        |error| <= 0.012, max <= 0.06; other pixels within 8-bit quantisation); 3 (36 samples)
        is the more accurate choice (measured about half the edge error) at about half
        the speed; 1 is fast but does not meet the tolerance.
    multisample : {4, 0, 2, 8, 16}, default 4
        OpenGL multisamples per sample (resolved by a box filter); 0 for none. The GL stack must
        give exactly this count (checked at the first render: llvmpipe offers 0 and 4 only,
        and rounds 2 up to 4), else the render raises ``ValueError``.

    Notes
    -----
    ``continuous_in_time = False``: the image jumps as samples flip, so the converter samples
    by ESIM's predicted rule (see :mod:`evedge.sim.converter`). :meth:`depth`, :meth:`flow` and
    :meth:`flow_at` are exact at pixel centres (ray casting against the triangles, no GL). The
    OpenGL context is created by the first render of an intensity or edge map; :meth:`close`
    frees it.

    Examples
    --------
    >>> from evedge.sim.trajectory import CameraTrajectory
    >>> tr = CameraTrajectory((0, 0, 0), (0, 0, 0), (0, 0, 0), (0, 0, 0))
    >>> plane = primitive_mesh("plane", (2.0, 2.0, 1.0), 0.25).transformed(np.eye(3), (0, 0, 3))
    >>> with RasterMeshRenderer(32, 24, 30.0, 30.0, 15.5, 11.5, [plane], tr, supersample=1) as r:
    ...     image = r.intensity(0.0)
    >>> round(float(image[12, 16]), 3)
    0.251
    """

    continuous_in_time = False

    def __init__(self, width, height, fx, fy, cx, cy, meshes, trajectory, background=0.5, supersample=2,
                 multisample=4):
        self._set_camera(width, height, fx, fy, cx, cy, background, trajectory, supersample)
        meshes = list(meshes)
        for k, m in enumerate(meshes):
            if not isinstance(m, SceneMesh):
                raise TypeError(f"meshes[{k}] must be a SceneMesh, got {type(m).__name__}")
        if isinstance(multisample, bool) or multisample not in (0, 2, 4, 8, 16):
            raise ValueError(f"multisample must be 0, 2, 4, 8 or 16 (llvmpipe gives 0 and 4), got {multisample!r}")
        self.multisample = int(multisample)
        self.meshes = tuple(meshes)
        if meshes:
            tris = np.concatenate([m.vertices_m[m.faces] for m in meshes])  # (T, 3, 3)
            self._lo = np.array([m.vertices_m.min(axis=0) for m in meshes])
            self._hi = np.array([m.vertices_m.max(axis=0) for m in meshes])
        else:
            tris = np.zeros((0, 3, 3))
            self._lo = self._hi = np.zeros((0, 3))
        self._v0 = np.ascontiguousarray(tris[:, 0])
        self._e1 = np.ascontiguousarray(tris[:, 1] - tris[:, 0])
        self._e2 = np.ascontiguousarray(tris[:, 2] - tris[:, 0])
        self._cache_t = None
        self._cache = None

    # -- OpenGL ---------------------------------------------------------------------------
    def _build_gl(self):
        pyrender, GL = _import_pyrender()
        s = self.supersample
        self._flags = pyrender.RenderFlags.FLAT
        scene = pyrender.Scene(bg_color=[self.background] * 3 + [1.0], ambient_light=[0.0, 0.0, 0.0])

        def corners_and_colours(meshes):
            corners = np.concatenate([m.vertices_m[m.faces].reshape(-1, 3) for m in meshes]).astype(np.float32)
            value = np.concatenate([m.corner_intensity.reshape(-1) if m.corner_intensity is not None
                                    else np.ones(3 * m.faces.shape[0]) for m in meshes])
            colours = np.repeat(value[:, None], 4, axis=1).astype(np.float32)
            colours[:, 3] = 1.0
            return corners, colours

        # the untextured meshes are drawn as one primitive (one draw call: pyrender's per-draw
        # Python overhead dominates a small render), each textured one as its own
        plain = [m for m in self.meshes if m.texture is None]
        parts = ([(plain, None, None)] if plain else []) + [([m], m.texture, m.uv) for m in self.meshes
                                                            if m.texture is not None]
        for group, tex, uv in parts:
            corners, colours = corners_and_colours(group)
            texture = texcoords = None
            if tex is not None:
                image = np.round(tex * 255.0).astype(np.uint8)  # pyrender flips rows (row 0: v = 1)
                texture = pyrender.Texture(source=np.repeat(image[..., None], 3, axis=2), source_channels="RGB")
                texcoords = uv[group[0].faces].reshape(-1, 2).astype(np.float32)
            material = pyrender.MetallicRoughnessMaterial(baseColorFactor=[1.0, 1.0, 1.0, 1.0], metallicFactor=0.0,
                                                          baseColorTexture=texture, doubleSided=True)
            prim = pyrender.Primitive(positions=corners, color_0=colours, texcoord_0=texcoords, material=material,
                                      mode=GL.GL_TRIANGLES)
            scene.add(pyrender.Mesh([prim]))
        self._add_camera(pyrender, scene)
        self._renderer = _offscreen(pyrender, _grey_renderer_class(pyrender, GL, self.multisample), s * self.width,
                                    s * self.height)

    def _check_open(self):
        if self._closed:
            raise RuntimeError("RasterMeshRenderer is closed")

    def _render(self, t_s: float):
        """(intensity (H, W), samples (sH, sW)) at ``t_s`` (the last one cached)."""
        t_s = _finite(t_s, "t_s")
        self._check_open()
        if self._cache_t != t_s:
            grey = self._draw(t_s)
            if self.supersample == 1:
                image = grey * (1.0 / 255.0)
            else:  # the s x s box mean (INTER_AREA at an integer factor), float32: exact to 1e-7
                import cv2

                image = cv2.resize(grey.astype(np.float32), (self.width, self.height),
                                   interpolation=cv2.INTER_AREA).astype(np.float64) * (1.0 / 255.0)
            samples = grey
            self._cache_t, self._cache = t_s, (image, samples)
        return self._cache

    # -- public ---------------------------------------------------------------------------
    def intensity(self, t_s: float) -> np.ndarray:
        """Linear intensity (H, W) float64 in [0, 1]: the mean of each pixel's ``s x s`` samples."""
        return self._render(t_s)[0].copy()

    def depth(self, t_s: float) -> np.ndarray:
        """Exact z-depth (H, W) float64 in metres at the pixel centres; ``inf`` where nothing is seen.

        By ray casting against every triangle (numba, no GL), so its cost grows with pixels x
        triangles (about 5 ms at 240x180 for 50 triangles): the depth buffer of the multisampled
        render holds one sample that is not at the pixel centre (1 % off on oblique faces).
        """
        t_s = _finite(t_s, "t_s")
        self._check_open()
        rot, centre = self.trajectory.rotation(t_s), self.trajectory.position(t_s)
        out = np.empty(self._x.size)
        _first_hit_depth_kernel(self._x.ravel(), self._y.ravel(), np.ascontiguousarray(rot[None]),
                                np.ascontiguousarray(centre[None]), self._v0, self._e1, self._e2, ZNEAR_M, out)
        return out.reshape(self.height, self.width)

    def flow(self, t_s: float) -> np.ndarray:
        """Motion field (2, H, W) float64 in px/s at the pixel centres, from :meth:`depth` and the camera motion."""
        t_s = _finite(t_s, "t_s")
        inv_z = 1.0 / self.depth(t_s)
        rot = self.trajectory.rotation(t_s)
        v_cam = rot.T @ self.trajectory.linear_velocity(t_s)
        return np.stack(motion_field(self._x, self._y, inv_z, v_cam, self.trajectory.angular_velocity(t_s),
                                     self.fx, self.fy))

    def depth_at(self, x, y, t_s) -> np.ndarray:
        """Exact z-depth (N,) at image points ``(x, y)``, each at its own time (ray casting; inf: nothing)."""
        self._check_open()
        x, y, t = (np.asarray(a, dtype=np.float64).reshape(-1) for a in (x, y, t_s))
        if not (x.size == y.size == t.size):
            raise ValueError(f"depth_at: x, y and t_s must have one length, got {x.size}, {y.size}, {t.size}")
        rot, centre, _, _ = self.trajectory.kinematics(t)
        out = np.empty(x.size)
        _first_hit_depth_kernel((x - self.cx) / self.fx, (y - self.cy) / self.fy, np.ascontiguousarray(rot),
                                np.ascontiguousarray(centre), self._v0, self._e1, self._e2, ZNEAR_M, out)
        return out

    def flow_at(self, x, y, t_s) -> tuple[np.ndarray, np.ndarray]:
        """Motion field ``(vx, vy)`` (N,) in px/s at image points ``(x, y)``, each at its own time.

        The depth is found by casting the point's ray at its time against the triangles
        (:meth:`depth_at`), then the exact motion field follows (no rendering): the per-event
        truth of the converter, computed only where events occur.
        """
        x, y, t = (np.asarray(a, dtype=np.float64).reshape(-1) for a in (x, y, t_s))
        depth = self.depth_at(x, y, t)
        rot, _, vel, w = self.trajectory.kinematics(t)
        v_cam = np.einsum("nji,nj->ni", rot, vel)
        return motion_field((x - self.cx) / self.fx, (y - self.cy) / self.fy, 1.0 / depth, v_cam, w,
                            self.fx, self.fy)

    def edges(self, t_s: float) -> np.ndarray:
        """Edge map (H, W) bool: pixels whose ``s x s`` samples, or those of a neighbouring sample
        across the pixel border, differ by more than 2/255 (an intensity discontinuity crosses it;
        silhouettes and texture edges alike, at the sample spacing's accuracy)."""
        samples = self._render(t_s)[1]
        s = self.supersample
        marked = np.zeros(samples.shape, dtype=bool)
        for axis in (0, 1):
            jump = np.abs(np.diff(samples.astype(np.int16), axis=axis)) > 2
            a = [slice(None)] * 2
            b = [slice(None)] * 2
            a[axis], b[axis] = slice(1, None), slice(None, -1)
            marked[tuple(a)] |= jump
            marked[tuple(b)] |= jump
        return marked.reshape(self.height, s, self.width, s).any(axis=(1, 3))

    def max_speed_px_s(self, t0_s: float, t1_s: float) -> float:
        """Upper bound of the image speed over ``[t0_s, t1_s]`` (:func:`~evedge.sim._motion_field.image_speed_bound`
        with the meshes' bounding boxes)."""
        return image_speed_bound(self, t0_s, t1_s, self._lo, self._hi)

    def _drop_caches(self) -> None:
        self._cache_t = self._cache = None
