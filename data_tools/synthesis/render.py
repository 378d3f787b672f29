"""Synthetic multi-view images of a person: a smooth mesh, shaded and z-buffered over a cluttered room.

The rendered person is deliberately *not* the tracker's body model, so that
tracking is not graded on its own assumptions:

* every segment is a closed, smooth tube (trimesh mesh) whose ends are rounded
  caps, so joints are rounded and neighbouring parts overlap;
* widths (radii and cross-section depth) are perturbed per segment and per seed
  by a factor in [0.9, 1.1] from the subject's shape;
* clothing colours (shirt, trousers, shoes, skin) are drawn per seed.

Shading is Lambertian with one directional light plus ambient light, with
smooth (interpolated) vertex normals. The static scene (floor tiles, panelled
walls with posters, furniture-like blocks, an optional occluder) is ray-cast /
rasterised once per camera into a background plate and depth buffer; each
frame the person is rasterised against that depth buffer, so furniture and the
occluder hide the person correctly. Images are RGB ``H x W x 3`` uint8.
Units: millimetres, pixels.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import trimesh

from data_tools.synthesis.raster import rasterize
from tracker.core.body import BodyModel
from tracker.core.cameras import Camera, CameraRig
from tracker.core.kinematics import forward_kinematics

#: Direction *towards* the light (world, unit): high, in front-left of the room.
LIGHT_DIRECTION = np.array([0.35, 0.25, 0.9]) / np.linalg.norm([0.35, 0.25, 0.9])
AMBIENT = 0.35
DIFFUSE = 0.65

# Cap heights as a fraction of the end radius: full hemispheres at limb joints,
# flattened caps where a wide segment would otherwise bulge past its neighbour.
_CAP = {"pelvis": (0.35, 0.3), "torso": (0.3, 0.35), "head": (0.5, 0.7), "hand": (0.6, 0.6), "foot": (0.7, 0.6)}


def _part(name: str) -> str:
    return name.replace("left_", "").replace("right_", "")


def _tube_mesh(length: float, r0: float, r1: float, depth: float, cap0: float, cap1: float,
               n_around: int = 20, n_cap: int = 5, n_body: int = 6) -> trimesh.Trimesh:
    """A closed tube along +z from 0 to ``length`` (mm) with elliptical cross-section and rounded caps."""
    th = np.linspace(0.0, np.pi / 2, n_cap + 1)
    prof_z = [-cap0 * r0 * np.cos(th[1:]), np.linspace(0.0, length, n_body + 2)[1:-1],
              length + cap1 * r1 * np.cos(th[::-1][:-1])]
    prof_r = [r0 * np.sin(th[1:]), r0 + (r1 - r0) * np.linspace(0.0, 1.0, n_body + 2)[1:-1],
              r1 * np.sin(th[::-1][:-1])]
    z = np.concatenate(prof_z)
    r = np.concatenate(prof_r)
    phi = np.linspace(0.0, 2 * np.pi, n_around, endpoint=False)
    ring = np.stack([np.cos(phi), depth * np.sin(phi)], axis=1)  # n_around x 2
    verts = np.concatenate([
        [[0.0, 0.0, -cap0 * r0]],
        np.column_stack([(r[:, None, None] * ring[None]).reshape(-1, 2), np.repeat(z, n_around)]),
        [[0.0, 0.0, length + cap1 * r1]],
    ])
    n_rings = len(z)
    faces = []
    idx = lambda i, j: 1 + i * n_around + (j % n_around)  # noqa: E731
    j = np.arange(n_around)
    faces.append(np.column_stack([np.zeros(n_around, int), idx(0, j + 1), idx(0, j)]))
    for i in range(n_rings - 1):
        faces.append(np.column_stack([idx(i, j), idx(i, j + 1), idx(i + 1, j + 1)]))
        faces.append(np.column_stack([idx(i, j), idx(i + 1, j + 1), idx(i + 1, j)]))
    top = len(verts) - 1
    faces.append(np.column_stack([np.full(n_around, top), idx(n_rings - 1, j), idx(n_rings - 1, j + 1)]))
    mesh = trimesh.Trimesh(verts, np.concatenate(faces), process=False)
    trimesh.repair.fix_normals(mesh)
    return mesh


@dataclass
class PersonMesh:
    """Per-segment meshes in segment coordinates, concatenated: ``vertices`` ``N x 3``, ``normals`` ``N x 3``,
    ``segment_of_vertex`` ``(N,)``, ``faces`` ``F x 3``, ``colours`` ``F x 3`` (RGB in [0, 1]),
    ``width_factors`` ``(S,)`` (the per-segment width perturbation)."""

    vertices: np.ndarray
    normals: np.ndarray
    segment_of_vertex: np.ndarray
    faces: np.ndarray
    colours: np.ndarray
    width_factors: np.ndarray


_SKIN = [(0.87, 0.69, 0.57), (0.62, 0.45, 0.34), (0.95, 0.8, 0.7), (0.45, 0.32, 0.25)]
_SHIRT = [(0.75, 0.15, 0.15), (0.15, 0.35, 0.7), (0.9, 0.85, 0.3), (0.2, 0.55, 0.3), (0.85, 0.85, 0.85)]
_TROUSERS = [(0.15, 0.17, 0.3), (0.3, 0.25, 0.2), (0.1, 0.1, 0.1), (0.45, 0.5, 0.55)]
_SHOES = [(0.08, 0.08, 0.08), (0.55, 0.3, 0.15), (0.9, 0.9, 0.9)]


def person_mesh(model: BodyModel, rng: np.random.Generator, width_jitter: float = 0.1) -> PersonMesh:
    """Build the rendered person for ``model``'s segments, widths perturbed by up to ``width_jitter``."""
    pick = lambda table: np.asarray(table[rng.integers(len(table))], float)  # noqa: E731
    skin, shirt, trousers, shoes = pick(_SKIN), pick(_SHIRT), pick(_TROUSERS), pick(_SHOES)
    colour_of = {"head": skin, "hand": skin, "lower_arm": skin, "torso": shirt, "upper_arm": shirt,
                 "pelvis": trousers, "upper_leg": trousers, "lower_leg": trousers, "foot": shoes}
    factors = rng.uniform(1.0 - width_jitter, 1.0 + width_jitter, size=len(model.segments))
    depth_factors = rng.uniform(1.0 - width_jitter / 2, 1.0 + width_jitter / 2, size=len(model.segments))
    verts, normals, seg_of, faces, colours = [], [], [], [], []
    offset = 0
    for k, seg in enumerate(model.segments):
        part = _part(seg.name)
        cap0, cap1 = _CAP.get(part, (1.0, 1.0))
        f = factors[k]
        mesh = _tube_mesh(seg.length, seg.radius_proximal * f, seg.radius_distal * f,
                          seg.depth_scale * depth_factors[k], cap0, cap1)
        verts.append(mesh.vertices)
        normals.append(mesh.vertex_normals)
        seg_of.append(np.full(len(mesh.vertices), k))
        faces.append(mesh.faces + offset)
        colours.append(np.tile(colour_of.get(part, shirt), (len(mesh.faces), 1)))
        offset += len(mesh.vertices)
    return PersonMesh(np.concatenate(verts), np.concatenate(normals), np.concatenate(seg_of),
                      np.concatenate(faces), np.concatenate(colours), factors)


# ---------------------------------------------------------------------------
# Static scene
# ---------------------------------------------------------------------------

@dataclass
class Room:
    """A room around the capture area: floor z = 0, walls at ``|x|, |y| = half_size``, ceiling (mm)."""

    half_size: float = 7000.0
    ceiling: float = 3500.0
    tile: float = 600.0
    seed: int = 0
    boxes: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list)  # (min, max, rgb)


def make_room(rng: np.random.Generator, rig: CameraRig, occluder: bool = False) -> Room:
    """A room with furniture-like blocks near the walls (clear of every camera), and optionally an occluder:
    a 0.35 m x 0.35 m x 1.9 m pillar between the first camera and the capture area, 0.5 m to its side."""
    room = Room(seed=int(rng.integers(1 << 30)))
    cams = np.array([c.centre[:2] for c in rig.cameras])
    placed = 0
    while placed < 9:
        side = rng.integers(4)
        along = rng.uniform(-6000, 6000)
        inward = rng.uniform(300, 1300)
        size = np.array([rng.uniform(500, 1500), rng.uniform(400, 900), rng.choice([450, 750, 900, 1200, 1800])])
        centre = {0: (6700 - inward, along), 1: (-6700 + inward, along), 2: (along, 6700 - inward),
                  3: (along, -6700 + inward)}[side]
        ext = size[[0, 1]] if side < 2 else size[[1, 0]]
        lo = np.array([centre[0] - ext[0] / 2, centre[1] - ext[1] / 2, 0.0])
        hi = np.array([centre[0] + ext[0] / 2, centre[1] + ext[1] / 2, size[2]])
        if np.any(np.abs(lo[:2]) > 6990) or np.any(np.abs(hi[:2]) > 6990):
            continue
        near_cam = np.any(np.all((cams > lo[:2] - 1200) & (cams < hi[:2] + 1200), axis=1))
        if near_cam:
            continue
        room.boxes.append((lo, hi, rng.uniform(0.15, 0.8, 3)))
        placed += 1
    if occluder:
        c = rig.cameras[0].centre
        d = c[:2] / np.linalg.norm(c[:2])
        centre = d * 2600.0 + np.array([-d[1], d[0]]) * 500.0
        room.boxes.append((np.array([centre[0] - 175, centre[1] - 175, 0.0]),
                           np.array([centre[0] + 175, centre[1] + 175, 1900.0]), np.array([0.55, 0.5, 0.45])))
    return room


def _hash_noise(ix: np.ndarray, iy: np.ndarray, seed: int) -> np.ndarray:
    """Deterministic pseudo-random values in [0, 1) for integer lattice points."""
    h = (ix.astype(np.int64) * 73856093) ^ (iy.astype(np.int64) * 19349663) ^ (seed * 83492791)
    h = (h ^ (h >> 13)) * 1274126177
    return ((h ^ (h >> 16)) & 0xFFFF) / 65536.0


def _floor_colour(x: np.ndarray, y: np.ndarray, room: Room) -> np.ndarray:
    t = room.tile
    ix, iy = np.floor(x / t), np.floor(y / t)
    base = np.where(((ix + iy) % 2 == 0)[..., None], [0.62, 0.55, 0.45], [0.45, 0.38, 0.3])
    tint = 0.85 + 0.3 * _hash_noise(ix, iy, room.seed)[..., None]
    grain = 0.9 + 0.1 * np.sin(x / 23.0 + 3 * np.sin(y / 170.0))[..., None]
    fx, fy = x / t - ix, y / t - iy
    grout = ((np.minimum(fx, 1 - fx) < 0.02) | (np.minimum(fy, 1 - fy) < 0.02))[..., None]
    return np.where(grout, 0.25, base * tint * grain)


def _wall_colour(u: np.ndarray, z: np.ndarray, wall: int, room: Room) -> np.ndarray:
    panel = np.floor(u / 800.0)
    n1 = _hash_noise(panel, np.full_like(panel, wall), room.seed)
    n2 = _hash_noise(panel, np.full_like(panel, wall + 7), room.seed)
    n3 = _hash_noise(panel, np.full_like(panel, wall + 13), room.seed)
    colour = np.stack([0.55 + 0.35 * n1, 0.5 + 0.35 * n2, 0.45 + 0.35 * n3], axis=-1)
    # Posters on some panels: a rectangle with stripes.
    pu = u / 800.0 - panel
    has_poster = _hash_noise(panel, np.full_like(panel, wall + 29), room.seed) > 0.45
    in_poster = has_poster & (pu > 0.2) & (pu < 0.8) & (z > 1200) & (z < 2100)
    stripes = (np.sin(z / 35.0 + 6 * n1) > 0)[..., None]
    poster = np.where(stripes, np.stack([n2, n3, n1], -1), np.stack([1 - n3, 0.2 + 0.5 * n1, 1 - n2], -1))
    colour = np.where(in_poster[..., None], poster, colour)
    skirting = (z < 120)[..., None]
    return np.where(skirting, 0.2, colour)


def _pixel_rays(camera: Camera) -> np.ndarray:
    """World directions ``H x W x 3`` of the pixel rays, scaled to unit depth (camera z = 1)."""
    u, v = np.meshgrid(np.arange(camera.width, dtype=float), np.arange(camera.height, dtype=float))
    yn = (v - camera.cy) / camera.fy
    xn = (u - camera.cx) / camera.fx - camera.skew * yn
    d_cam = np.stack([xn, yn, np.ones_like(xn)], axis=-1)
    return d_cam @ camera.R  # rows: R^T d


def box_mesh(lo: np.ndarray, hi: np.ndarray) -> trimesh.Trimesh:
    return trimesh.creation.box(bounds=np.stack([lo, hi]))


def render_background(camera: Camera, room: Room) -> tuple[np.ndarray, np.ndarray]:
    """The static scene seen by ``camera``: RGB ``H x W x 3`` float in [0, 1] and depth ``H x W`` (mm).

    Floor, walls and ceiling are ray-cast per pixel; furniture blocks are
    rasterised with flat Lambertian shading. Distortion-free cameras only
    (the synthetic rigs); the per-pixel rays ignore ``dist``.
    """
    if any(camera.dist):
        raise ValueError(f"camera {camera.name}: synthetic backgrounds need a distortion-free camera")
    H, W = camera.height, camera.width
    rays = _pixel_rays(camera)
    c = camera.centre
    big = np.inf
    best = np.full((H, W), big)
    colour = np.zeros((H, W, 3))
    normal = np.zeros((H, W, 3))
    planes = [(2, 0.0, None), (2, room.ceiling, None), (0, room.half_size, 0), (0, -room.half_size, 1),
              (1, room.half_size, 2), (1, -room.half_size, 3)]
    with np.errstate(divide="ignore", invalid="ignore"):
        for axis, value, wall in planes:
            t = (value - c[axis]) / rays[..., axis]
            hit = (t > 0) & (t < best)
            if not np.any(hit):
                continue
            p = c + t[..., None] * rays
            best = np.where(hit, t, best)
            if wall is None and value == 0.0:
                col = _floor_colour(p[..., 0], p[..., 1], room)
            elif wall is None:
                col = np.full((H, W, 3), 0.85)
            else:
                u = p[..., 1] if axis == 0 else p[..., 0]
                col = _wall_colour(u, p[..., 2], wall, room)
            n = np.zeros(3)
            n[axis] = -np.sign(value) if value != 0 else 1.0
            colour = np.where(hit[..., None], col, colour)
            normal = np.where(hit[..., None], n, normal)
    shade = AMBIENT + DIFFUSE * np.clip(normal @ LIGHT_DIRECTION, 0.0, 1.0)
    image = colour * shade[..., None]
    depth = best.copy()
    for lo, hi, rgb in room.boxes:
        mesh = box_mesh(lo, hi)
        pix, z = camera.project(mesh.vertices)
        fn = mesh.face_normals
        front = np.einsum("fi,fi->f", fn, c - mesh.vertices[mesh.faces[:, 0]]) > 0
        frags = rasterize(pix, z, mesh.faces, W, H, zbuffer=depth, front=front)
        if frags.pixel.size == 0:
            continue
        n = fn[frags.face]
        box_shade = AMBIENT + DIFFUSE * np.clip(n @ LIGHT_DIRECTION, 0.0, 1.0)
        # A little texture on furniture: soft vertical bands.
        px = frags.pixel % W
        band = 0.9 + 0.1 * np.sin(px / 5.0 + rgb[0] * 10)
        image.reshape(-1, 3)[frags.pixel] = rgb * (box_shade * band)[:, None]
        depth.reshape(-1)[frags.pixel] = frags.depth
    return np.clip(image, 0.0, 1.0), depth


# ---------------------------------------------------------------------------
# Frames
# ---------------------------------------------------------------------------

@dataclass
class PersonRender:
    """One view of the person: ``colour`` RGB ``H x W x 3`` float (only where ``mask``), ``mask`` ``H x W``
    bool (visible person pixels, after occlusion by the scene)."""

    colour: np.ndarray
    mask: np.ndarray


def render_person(person: PersonMesh, model: BodyModel, pose: np.ndarray, rig: CameraRig,
                  scene_depths: list[np.ndarray]) -> list[PersonRender]:
    """Rasterise the person at ``pose`` ``(D,)`` into every camera of ``rig``, hidden by ``scene_depths``."""
    frames = forward_kinematics(model, pose).segment_frames()  # S x 4 x 4
    R = frames[person.segment_of_vertex, :3, :3]
    verts = np.einsum("nij,nj->ni", R, person.vertices) + frames[person.segment_of_vertex, :3, 3]
    normals = np.einsum("nij,nj->ni", R, person.normals)
    f = person.faces
    face_n = np.cross(verts[f[:, 1]] - verts[f[:, 0]], verts[f[:, 2]] - verts[f[:, 0]])
    pix, depth = rig.project(verts)  # V x N x 2, V x N
    out = []
    for v, cam in enumerate(rig.cameras):
        H, W = cam.height, cam.width
        front = np.einsum("fi,fi->f", face_n, cam.centre - verts[f[:, 0]]) > 0
        frags = rasterize(pix[v], depth[v], f, W, H, zbuffer=scene_depths[v], front=front)
        colour = np.zeros((H * W, 3))
        mask = np.zeros(H * W, bool)
        if frags.pixel.size:
            n = np.einsum("mk,mki->mi", frags.bary, normals[f[frags.face]])
            n /= np.linalg.norm(n, axis=1, keepdims=True)
            shade = AMBIENT + DIFFUSE * np.clip(n @ LIGHT_DIRECTION, 0.0, 1.0)
            colour[frags.pixel] = person.colours[frags.face] * shade[:, None]
            mask[frags.pixel] = True
        out.append(PersonRender(colour.reshape(H, W, 3), mask.reshape(H, W)))
    return out


def compose(background: np.ndarray, person: PersonRender, gain: float, noise_std: float,
            rng: np.random.Generator) -> np.ndarray:
    """Final 8-bit RGB image: person over background, global light ``gain``, Gaussian sensor noise
    (``noise_std`` grey levels of 255)."""
    img = np.where(person.mask[..., None], person.colour, background) * (255.0 * gain)
    if noise_std > 0:
        img = img + rng.normal(0.0, noise_std, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)
