"""meshcat views of the human model and the PAM robot: bones, muscles, PAMs and sweeps.

A view shows, in one self-contained web page (meshcat's static HTML, three.js inlined):

* the skeleton: each body's bone meshes (:func:`pamkin.opensim.vtp.body_meshes`) placed with its body
  transform, or simple shapes without a geometry folder (a cylinder from the body origin to
  each child's joint origin, a sphere at the origin);
* human muscles (Gait2392, full activation, static equilibrium) as thin cylinders of radius
  :data:`MUSCLE_RADIUS` through their path points in effect (conditional points only in range);
* robot PAMs along their routes. A route holds a fitting (``fitting_length_m``), the PAM itself
  (length rest·(1 − strain) = (L − tendon)/transmission − 2·fitting), the second fitting and the
  artificial tendon; the PAM with its fittings sits where ``pamkin audit`` puts it
  (:func:`pam_placements`, :mod:`pamkin.robot.pam_body`): at the anchored end of its mount segment (the
  design's ``pam_at``), bending over the route's points where it does not fit on one segment. The
  PAM is a cylinder of its Festo nominal (inner) diameter; the whole route is underlaid by a thin
  dark-grey cylinder, so what shows beyond the PAM is fittings + tendon. A PAM longer than its route
  (negative tendon, a flagged design defect) is clipped at the route's ends.
* colours by force [N] or strain [-] on one scale for muscles and PAMs (legend in the page
  header); a PAM outside its strain range (a dead zone) is drawn in :data:`DEAD_ZONE_COLOR`.

Human and robot stand side by side (the robot shifted to the right of the picture, at the same
distance from the camera) or overlaid on one skeleton; the camera looks from the front-right.
A range-of-motion sweep of one coordinate is a meshcat animation (body transforms, segment
transforms and lengths, colours), contained in the static page. meshcat is Z-up and OpenSim
Y-up: the scene root is rotated +90° about X (and shifted to put the scene's centre at the
origin, which meshcat's camera orbits).

The page is written without a meshcat server: :class:`StaticWindow` records the commands a
:class:`meshcat.Visualizer` sends and :meth:`meshcat.Visualizer.static_html` packs them, with
the animation loaded after every object exists.
"""

from __future__ import annotations

import base64
import html as _html
import os
import shutil
import subprocess
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pamkin._resources import DEFAULT_GEOMETRY as _DEFAULT_GEOMETRY
from pamkin.audit.measure import random_poses
from pamkin.errors import ConfigurationError, PamkinError, RangeWarning
from pamkin.human.rom import load_rom
from pamkin.robot.biped import placements
from pamkin.robot.pam_body import body_interval, route_positions
from pamkin.robot.rollers import roller_world
from pamkin.outputs import write_file

__all__ = ["ColorScale", "StaticWindow", "View", "build_view", "screenshot", "simple_bone_meshes"]

#: OpenSim's Geometry folder beside the repository (``../shared/opensim-models/Geometry``).
DEFAULT_GEOMETRY = _DEFAULT_GEOMETRY
#: Radius of the human muscle cylinders [m].
MUSCLE_RADIUS = 0.004
#: Radius of the thin cylinders under each PAM route (fittings and artificial tendon) [m].
TENDON_RADIUS = 0.0015
BONE_COLOR = 0xE6DCC3
ROBOT_BONE_COLOR = 0xB4C3D2
TENDON_COLOR = 0x404040
#: Colour of the rollers (cable guides, :mod:`pamkin.robot.rollers`).
ROLLER_COLOR = 0x9A9A9A
#: Colour of a PAM outside its strain range (stretched beyond Festo's pretension limit or
#: contracted beyond kmax).
DEAD_ZONE_COLOR = (1.0, 0.0, 1.0)
BACKGROUND = (1.0, 1.0, 1.0)
#: Height of the page header holding title and legend [CSS px]; the 3-D pane fills the rest.
HEADER_PX = 64
#: The colour map and the part of it used (its darkest ends are left out).
COLORMAP = ("turbo", 0.08, 0.92)
CHROMIUM = "/usr/bin/chromium"
#: Camera direction: degrees from the front toward the model's right, and above the horizontal.
VIEW_AZIMUTH, VIEW_ELEVATION = 40.0, 10.0


# ----------------------------------------------------------------------------- page without server
class StaticWindow:
    """A meshcat window without a server: records the scene for ``Visualizer.static_html()``.

    Use ``meshcat.Visualizer(window=StaticWindow(...))``. The scene is kept as the meshcat
    server keeps it (one tree of nodes with object, properties and transform); the page replays
    the commands in order and loads the animation last, after every object exists.

    Args:
        title: Page title.
        header_html: HTML shown above the 3-D pane (title, legend), :data:`HEADER_PX` high.
    """

    def __init__(self, title: str = "pamkin", header_html: str = "") -> None:
        from meshcat.servers.tree import SceneTree  # noqa: PLC0415

        self.tree = SceneTree()
        self.animation: bytes | None = None
        self.title = title
        self.header_html = header_html

    def send(self, command) -> None:
        import umsgpack  # noqa: PLC0415
        from meshcat.servers.tree import SceneTree, find_node  # noqa: PLC0415

        data = command.lower()
        packed = umsgpack.packb(data, force_float_precision="single")   # float32, as three.js uses
        path = [p for p in data["path"].split("/") if p]
        kind = data["type"]
        if kind == "set_animation":
            self.animation = packed
            return
        if kind == "delete":
            if path:
                parent = find_node(self.tree, path[:-1])
                parent.pop(path[-1], None)
            else:
                self.tree = SceneTree()
            return
        node = find_node(self.tree, path)
        if kind == "set_object":
            node.object = packed
            node.properties = []
        elif kind == "set_transform":
            node.transform = packed
        elif kind == "set_property":
            node.properties.append(packed)
        else:
            raise ValueError(f"meshcat command {kind!r} has no static form")

    def commands(self) -> list[bytes]:
        """The recorded commands in replay order (msgpack)."""
        from meshcat.servers.tree import walk  # noqa: PLC0415

        out = []
        for node in walk(self.tree):
            if node.object is not None:
                out.append(node.object)
            out.extend(node.properties)
            if node.transform is not None:
                out.append(node.transform)
        if self.animation is not None:
            out.append(self.animation)
        return out

    def get_scene(self) -> str:
        """The self-contained page (what ``Visualizer.static_html()`` returns)."""
        import meshcat  # noqa: PLC0415

        js = (Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js").read_text()
        blobs = ",\n".join(f'"{base64.b64encode(c).decode()}"' for c in self.commands())
        return f"""<!DOCTYPE html>
<html>
<head><meta charset="utf-8"><title>{_html.escape(self.title)}</title>
<style>
body {{ margin: 0; font-family: sans-serif; }}
#pamkin-header {{ height: {HEADER_PX}px; box-sizing: border-box; padding: 4px 10px; overflow: hidden;
  font-size: 12px; line-height: 1.35; border-bottom: 1px solid #ccc; background: #fff; }}
.pamkin-line {{ white-space: nowrap; overflow: hidden; text-overflow: ellipsis; }}
#meshcat-pane {{ width: 100vw; height: calc(100vh - {HEADER_PX}px); overflow: hidden; position: relative; }}
</style></head>
<body>
<div id="pamkin-header">{self.header_html}</div>
<div id="meshcat-pane"></div>
<script>
{js}
</script>
<script>
var pane = document.getElementById("meshcat-pane");
var viewer = new MeshCat.Viewer(pane);
// meshcat sizes the canvas to the window's height; the pane is the window less the header
function pamkin_fit() {{ viewer.set_3d_pane_size(pane.offsetWidth, pane.offsetHeight); }}
window.addEventListener("resize", pamkin_fit, false);
requestAnimationFrame(pamkin_fit);
pamkin_fit();
viewer.gui.close();
viewer.gui.domElement.style.top = "{HEADER_PX}px";
var pamkin_commands = [
{blobs}
];
for (const b of pamkin_commands) {{
  viewer.handle_command_bytearray(Uint8Array.from(atob(b), c => c.charCodeAt(0)));
}}
</script>
</body>
</html>
"""

    def open(self):  # noqa: D102 - the Visualizer API; nothing to open without a server
        return self


# ----------------------------------------------------------------------------- colours
@dataclass(frozen=True)
class ColorScale:
    """Linear colour scale of muscle and PAM colours.

    Attributes:
        quantity: ``"force"`` or ``"strain"``.
        vmin: Value at the scale's low end.
        vmax: Value at the high end (values beyond are clipped).
        label: Legend text with unit.
    """

    quantity: str
    vmin: float
    vmax: float
    label: str

    def rgb(self, values: np.ndarray) -> np.ndarray:
        """Colours (..., 3) in [0, 1] of ``values``."""
        from matplotlib import colormaps  # noqa: PLC0415

        name, lo, hi = COLORMAP
        t = np.clip((np.asarray(values, float) - self.vmin) / (self.vmax - self.vmin), 0.0, 1.0)
        return colormaps[name](lo + (hi - lo) * t)[..., :3]

    def css_gradient(self, n: int = 11) -> str:
        stops = ", ".join(_css(c) for c in self.rgb(np.linspace(self.vmin, self.vmax, n)))
        return f"linear-gradient(to right, {stops})"


def _css(rgb) -> str:
    r, g, b = (round(255 * float(x)) for x in rgb)
    return f"#{r:02x}{g:02x}{b:02x}"


def _hex(rgb) -> int:
    r, g, b = (round(255 * float(x)) for x in rgb)
    return (r << 16) | (g << 8) | b


def _nice_ceil(x: float) -> float:
    if x <= 0:
        return 1.0
    e = 10 ** np.floor(np.log10(x))
    for m in (1, 1.5, 2, 2.5, 3, 4, 5, 6, 8, 10):
        if m * e >= x:
            return float(m * e)
    return float(10 * e)


# ----------------------------------------------------------------------------- geometry helpers
def _rot_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    T = np.eye(4)
    T[1:3, 1:3] = [[c, -s], [s, c]]
    return T


def _translation(p) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


def _cylinder_frames(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Transforms (K, 4, 4) taking a unit-height Y-axis cylinder centred at the origin onto the
    segments A→B (without the length scale), and the lengths (K,)."""
    d = B - A
    L = np.linalg.norm(d, axis=-1)
    y = np.where(L[:, None] > 1e-12, d / np.maximum(L, 1e-12)[:, None], [0.0, 1.0, 0.0])
    ref = np.where(np.abs(y[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 0.0, 1.0]])
    x = np.cross(y, ref)
    x /= np.linalg.norm(x, axis=-1, keepdims=True)
    z = np.cross(x, y)
    T = np.tile(np.eye(4), (len(A), 1, 1))
    T[:, :3, 0], T[:, :3, 1], T[:, :3, 2] = x, y, z
    T[:, :3, 3] = 0.5 * (A + B)
    return T, L


def _padded_segments(polyline: np.ndarray, n_seg: int) -> tuple[np.ndarray, np.ndarray]:
    """Segment ends (n_seg, 3) × 2 of a polyline; missing segments collapse onto its last point."""
    a = np.repeat(polyline[-1:], n_seg, axis=0)
    b = a.copy()
    k = len(polyline) - 1
    a[:k], b[:k] = polyline[:-1], polyline[1:]
    return a, b


def _clip_polyline(polyline: np.ndarray, s0: float, s1: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-segment pieces (S, 3) × 2 of a polyline between arc lengths s0 and s1 (empty pieces
    collapse to a point)."""
    A, B = polyline[:-1], polyline[1:]
    seg = np.linalg.norm(B - A, axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    lo = np.clip(s0 - s[:-1], 0.0, seg)
    hi = np.clip(s1 - s[:-1], 0.0, seg)
    hi = np.maximum(hi, lo)
    u = np.where(seg[:, None] > 0, (B - A) / np.maximum(seg, 1e-12)[:, None], 0.0)
    return A + u * lo[:, None], A + u * hi[:, None]


def simple_bone_meshes(model, q0: np.ndarray, radius: float = 0.012) -> dict[str, list]:
    """Stand-in bones without a geometry folder, in each body frame [m].

    A cylinder from the body origin to each child's joint origin (at configuration ``q0``) and a
    sphere at the origin; a body without children (toes, torso) gets a cylinder to twice its
    centre of mass.
    """
    import trimesh  # noqa: PLC0415

    st = model.kinematics.forward(np.atleast_2d(q0), warn_range=False)
    idx = {b: i for i, b in enumerate(model.bodies)}
    children: dict[str, list[str]] = {b: [] for b in model.bodies}
    for j in model.osim.joints:
        if j.parent in children:
            children[j.parent].append(j.child)
    out = {}
    for body in model.osim.bodies:
        i = idx[body.name]
        R, p = st.body_R[0, i], st.body_p[0, i]
        ends = [R.T @ (st.body_p[0, idx[c]] - p) for c in children[body.name]]
        if not ends:
            ends = [2.0 * np.asarray(body.mass_center)]
        parts = [trimesh.creation.icosphere(subdivisions=2, radius=1.6 * radius)]
        for e in ends:
            if np.linalg.norm(e) > 1e-6:
                parts.append(trimesh.creation.cylinder(radius=radius, segment=[np.zeros(3), e], sections=16))
        out[body.name] = [trimesh.util.concatenate(parts)]
    return out


# ----------------------------------------------------------------------------- the view
@dataclass
class View:
    """A built scene (see :func:`build_view`).

    Attributes:
        visualizer: The meshcat visualizer (its window is a :class:`StaticWindow`).
        frames: Configurations shown (F, n_coordinates) [rad, m]; F > 1 for a sweep.
        scale: Colour scale of muscles and PAMs.
        human_rgb: Muscle colours (F, n_muscles, 3).
        robot_rgb: PAM colours (F, n_pams, 3) (:data:`DEAD_ZONE_COLOR` in dead zones).
        title: Page title.
    """

    visualizer: object
    frames: np.ndarray
    scale: ColorScale
    human_rgb: np.ndarray
    robot_rgb: np.ndarray
    title: str

    def html(self) -> str:
        """The self-contained page (``meshcat.Visualizer.static_html()``)."""
        return self.visualizer.static_html()

    def save(self, path: str | os.PathLike) -> Path:
        """Write the page to ``path`` (:func:`pamkin.outputs.write_file`: atomically, or through a pipe)."""
        return write_file(path, self.html())


def sweep_frames(robot, coordinate: str, n: int, base: np.ndarray) -> np.ndarray:
    """Configurations (2n − 2, n_coordinates) sweeping ``coordinate`` over the design's range of
    motion and back (the other coordinates at ``base``).

    Raises:
        pamkin.errors.ConfigurationError: Unknown coordinate, or none in the range of motion.
    """

    if n < 2:
        raise ConfigurationError("a sweep needs at least 2 frames")
    side = "l" if coordinate.endswith("_l") else "r"
    rom = load_rom(robot.design.rom, side)
    q, _ = robot.model.grid([coordinate], n, rom=rom, base=dict(zip(robot.coordinates, base)))
    return np.concatenate([q, q[-2:0:-1]])


def build_view(human, robot, *, meshes: dict | None = None, layout: str = "side", color: str = "force",
               q: np.ndarray | None = None, sweep: str | None = None, n: int = 21, offset: float = 0.8,
               fps: float = 10.0) -> View:
    """Build a meshcat scene of the human model and a robot design.

    Args:
        human: The human :class:`pamkin.Model` (muscle forces at full activation).
        robot: A :class:`pamkin.robot.biped.PamRobot`.
        meshes: ``{body: [trimesh.Trimesh]}`` in body frames (:func:`pamkin.opensim.vtp.body_meshes`);
            None for simple shapes.
        layout: ``"side"`` (robot beside the human) or ``"overlay"`` (one skeleton).
        color: ``"force"`` [N] or ``"strain"`` (PAM contraction (rest − length)/rest; muscle
            fibre contraction 1 − l_M/l_opt) [-].
        q: Configuration (n_coordinates,) [rad, m] (default: every coordinate 0).
        sweep: Coordinate swept over the design's range of motion (an animation), or None.
        n: Samples of the sweep (the animation plays them forth and back).
        offset: Sideways distance of the robot in the ``side`` layout [m].
        fps: Animation frames per second.

    Raises:
        pamkin.errors.ConfigurationError: Bad layout, colour, configuration or sweep coordinate.
    """
    with warnings.catch_warnings():   # meshcat 0.3.2 imports zmq.eventloop.ioloop (deprecated)
        warnings.simplefilter("ignore", DeprecationWarning)
        import meshcat  # noqa: PLC0415
    import meshcat.geometry as g  # noqa: PLC0415
    from meshcat.animation import Animation  # noqa: PLC0415

    if layout not in ("side", "overlay"):
        raise ConfigurationError(f"layout must be 'side' or 'overlay', not {layout!r}")
    if color not in ("force", "strain"):
        raise ConfigurationError(f"color must be 'force' or 'strain', not {color!r}")
    q0 = np.zeros(len(human.coordinates)) if q is None else human.kinematics.as_q(q)[0]
    Q = sweep_frames(robot, sweep, n, q0) if sweep else q0[None, :]
    F = len(Q)
    with warnings.catch_warnings():   # the robot's range of motion may exceed Gait2392's GUI ranges
        warnings.simplefilter("ignore", RangeWarning)
        hk = human.kinematics.forward(Q, warn_range=False)
        hm = human.evaluate(Q)
        rk = robot.model.kinematics.forward(Q, warn_range=False)
        rs = robot.evaluate(Q)

    # colours
    if color == "force":
        hv, rv = hm.tendon_forces, rs.forces
        scale = ColorScale("force", 0.0, _nice_ceil(max(float(hv.max()), float(rv.max()))), "force [N]")
    else:
        hv, rv = 1.0 - hm.equilibrium.normalized_fiber_length, rs.strain
        scale = ColorScale("strain", -0.1, 0.5, "contraction [-] (PAM (rest − length)/rest, "
                                                "muscle fibre 1 − l/l_opt)")
    h_rgb = scale.rgb(hv)
    r_rgb = scale.rgb(rv)
    r_rgb[~rs.in_range] = DEAD_ZONE_COLOR

    dead = sorted({robot.names[k] for k in np.nonzero(~rs.in_range.all(axis=0))[0]})
    negative = [robot.names[k] for k in range(len(robot.names)) if robot.tendon[k] < 0]
    title = (f"pamkin: Gait2392 and robot design {robot.design.name}"
             + (f", sweep of {sweep}" if sweep else ""))
    header = _header(title, scale, layout, robot, dead, negative, sweep)
    window = StaticWindow(title, header)
    vis = meshcat.Visualizer(window=window)
    anim = Animation(default_framerate=fps) if F > 1 else None

    if meshes is None:
        meshes = simple_bone_meshes(human, q0)
    # beside the human as the camera sees it: along the picture's horizontal (the same distance from the camera)
    robot_origin = offset * _view_axes(VIEW_AZIMUTH, VIEW_ELEVATION)[1] if layout == "side" else np.zeros(3)
    groups = [("human", np.zeros(3), human, hk, BONE_COLOR)]
    if layout == "side":
        groups.append(("robot", robot_origin, robot.model, rk, ROBOT_BONE_COLOR))
    vis["pamkin/robot"].set_transform(_translation(robot_origin))
    corners = []      # points that the camera frames (OpenSim frame of the scene root)
    for name, origin, model, kin, bone_color in groups:
        vis[f"pamkin/{name}"].set_transform(_translation(origin))
        for i, body in enumerate(model.bodies):
            parts = meshes.get(body, [])
            T = np.tile(np.eye(4), (F, 1, 1))
            T[:, :3, :3], T[:, :3, 3] = kin.body_R[:, i], kin.body_p[:, i]
            node = f"pamkin/{name}/bones/{body}"
            if parts:
                v = np.concatenate([np.asarray(m.vertices) for m in parts])
                f = np.concatenate([np.asarray(m.faces) + off for m, off in
                                    zip(parts, np.cumsum([0] + [len(m.vertices) for m in parts[:-1]]))])
                vis[node].set_object(g.TriangularMeshGeometry(v, f), g.MeshLambertMaterial(color=bone_color))
                lo, hi = v.min(axis=0), v.max(axis=0)
                box = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
                corners.append(np.einsum("fij,kj->fki", T[:, :3, :3], box).reshape(-1, 3)
                               + np.repeat(T[:, :3, 3], 8, axis=0) + origin)
            _place(vis, anim, node, T)

    # human muscles (a conditional point may drop out: a fixed number of segments, some of zero length)
    lines = [human.paths.polylines(hk, f) for f in range(F)]
    for m, name in enumerate(human.muscles):
        n_seg = max(len(lines[f][m]) for f in range(F)) - 1
        ends = [_padded_segments(lines[f][m], n_seg) for f in range(F)]
        corners.append(np.concatenate([lines[f][m] for f in range(F)]))
        _cylinders(vis, anim, f"pamkin/human/muscles/{name}", ends, MUSCLE_RADIUS, h_rgb[:, m], basic=True)

    # robot PAMs: thin route (fittings + tendon), thick PAM where the audit puts it (pamkin.robot.pam_body)
    fit = robot.design.fitting_length_m
    routes = robot.polylines(rk)
    places = pam_placements(robot)
    for k, name in enumerate(robot.names):
        for i, r in enumerate(robot.rollers[k]):          # rollers: grey cylinders fixed in their bones
            b = robot.model.kinematics.frames.index(r.body)
            T = roller_transforms(r, rk.body_R[:, b], rk.body_p[:, b])
            node = f"pamkin/robot/pams/{name}/roller{i + 1}"
            vis[node].set_object(g.Cylinder(r.length_m, r.radius_m), g.MeshLambertMaterial(color=ROLLER_COLOR))
            _place(vis, anim, node, T)
        n_seg = max(len(routes[f][k]) for f in range(F)) - 1
        corners.append(np.concatenate([routes[f][k] for f in range(F)]) + robot_origin)
        node = f"pamkin/robot/pams/{name}"
        _cylinders(vis, anim, f"{node}/route", [_padded_segments(routes[f][k], n_seg) for f in range(F)],
                   TENDON_RADIUS, np.tile(_rgb(TENDON_COLOR), (F, 1)), basic=True)
        pts = route_positions(robot.paths, rk, k)
        place = places[k % len(places)]
        s0, s1 = body_interval(pts, place.segment, rs.pam_lengths[:, k] + 2 * fit, place.side)
        pieces = [_clip_polyline(pts[f], s0[f] + fit, max(s0[f] + fit, s1[f] - fit)) for f in range(F)]
        _cylinders(vis, anim, f"{node}/pam", pieces, robot.diameter[k] / 2000.0, r_rgb[:, k], basic=False)

    _frame_camera(vis, np.concatenate(corners))
    vis["/Grid"].set_property("visible", False)
    vis["/Axes"].set_property("visible", False)
    vis["/Background"].set_property("top_color", list(BACKGROUND))
    vis["/Background"].set_property("bottom_color", list(BACKGROUND))
    if anim is not None:
        vis.set_animation(anim, play=True, repetitions=1_000_000)
    return View(vis, Q, scale, h_rgb, r_rgb, title)


#: Random poses (the design's range of motion, the audit's stream and seed 0) over which the viewer finds
#: each PAM's mount segment and end (:func:`pam_placements`).
PLACEMENT_POSES = 300


def pam_placements(robot) -> list:
    """Where each PAM of ``robot`` (a :class:`pamkin.robot.biped.PamRobot`) sits on its route
    (:func:`pamkin.robot.pam_body.placement`: mount segment and anchored end) over :data:`PLACEMENT_POSES` random
    poses of its range of motion — the audit's rule on the first of the audit's random poses. One per
    PAM of the design (the left copy sits where the right one does)."""

    q = random_poses(robot.model, load_rom(robot.design.rom, "r"), PLACEMENT_POSES)
    return [place for place, _, _ in placements(robot.design, robot.model, q)]


def roller_transforms(r, R_body: np.ndarray, p_body: np.ndarray) -> np.ndarray:
    """(S, 4, 4) placements of a meshcat ``Cylinder`` (its axis is its y axis) drawing roller ``r``
    (:mod:`pamkin.robot.rollers`) at S placements of its body (R_body (S, 3, 3), p_body (S, 3))."""
    R, c = roller_world(r, R_body, p_body)
    T = np.tile(np.eye(4), (len(c), 1, 1))
    T[:, :3, :3] = R[:, :, [0, 2, 1]] * np.array([1.0, 1.0, -1.0])    # columns x, z, −y: right-handed
    T[:, :3, 3] = c
    return T


def _rgb(hex_color: int) -> np.ndarray:
    return np.array([(hex_color >> 16) & 255, (hex_color >> 8) & 255, hex_color & 255]) / 255.0


def _moves(x: np.ndarray, tol: float = 1e-7) -> bool:
    """True if frames ``x[f]`` differ from frame 0."""
    return bool(np.abs(x - x[:1]).max() > tol)


def _place(vis, anim, node: str, T: np.ndarray) -> None:
    """Static transform of frame 0, and one key per frame when animated and moving."""
    vis[node].set_transform(T[0])
    if anim is not None and _moves(T):
        for f in range(len(T)):
            anim.at_frame(vis, f)[node].set_transform(T[f])


def _cylinders(vis, anim, node: str, ends: list, radius: float, rgb: np.ndarray, basic: bool) -> None:
    """Cylinders on segments ``ends[f] = (A, B)`` (S, 3) per frame, coloured ``rgb[f]``."""
    import meshcat.geometry as g  # noqa: PLC0415

    F = len(ends)
    S = len(ends[0][0])
    frames = [_cylinder_frames(a, b) for a, b in ends]
    T = np.stack([fr[0] for fr in frames], axis=1)                 # (S, F, 4, 4)
    L = np.maximum(np.stack([fr[1] for fr in frames], axis=1), 1e-9)   # (S, F)
    recolor = anim is not None and _moves(rgb, 1e-3)
    material = g.MeshBasicMaterial if basic else g.MeshLambertMaterial
    for s in range(S):
        path = f"{node}/s{s}"
        geometry = g.Cylinder(1.0, radius)
        geometry.radialSegments = 12 if basic else 24
        vis[path].set_object(geometry, material(color=_hex(rgb[0])))
        T0 = T[s, 0].copy()
        T0[:3, 1] *= L[s, 0]
        vis[path].set_transform(T0)
        if anim is None:
            continue
        move = _moves(T[s]) or _moves(L[s])
        for f in range(F):
            fr = anim.at_frame(vis, f)
            if move:
                fr[path].set_transform(T[s, f])
                fr[path].set_property("scale", "vector3", [1.0, float(L[s, f]), 1.0])
            if recolor:
                fr[f"{path}/<object>"].set_property("material.color", "color", [float(c) for c in rgb[f]])


def _view_axes(azimuth_deg: float, elevation_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(back, right, up) unit vectors of the camera in the OpenSim frame: ``back`` points from the
    target to the camera, at ``azimuth_deg`` from the front (+X) toward the model's right (+Z)."""
    az, el = np.radians(azimuth_deg), np.radians(elevation_deg)
    back = np.array([np.cos(el) * np.cos(az), np.sin(el), np.cos(el) * np.sin(az)])
    right = np.cross([0.0, 1.0, 0.0], back)
    right /= np.linalg.norm(right)
    return back, right, np.cross(back, right)


def _frame_camera(vis, points_osim: np.ndarray, azimuth_deg: float = VIEW_AZIMUTH,
                  elevation_deg: float = VIEW_ELEVATION, fov_deg: float = 30.0, aspect: float = 1.45) -> None:
    """Centre ``points_osim`` (OpenSim frame, Y up, of the scene root) at the origin and place the
    default camera in front, to the right and slightly above, so that they fill a pane of
    width/height ≥ ``aspect``.
    """
    lo, hi = points_osim.min(axis=0), points_osim.max(axis=0)
    c = 0.5 * (lo + hi)
    back, right, up = _view_axes(azimuth_deg, elevation_deg)
    p = points_osim - c
    t = np.tan(np.radians(fov_deg) / 2)
    half_h, half_w, depth = np.abs(p @ up).max(), np.abs(p @ right).max(), np.abs(p @ back).max()
    dist = 1.15 * max(half_h / t, half_w / (t * aspect)) + depth
    # meshcat's orbit controls look at the world origin: move the scene's centre there
    vis["pamkin"].set_transform(_translation(-_rot_x(np.pi / 2)[:3, :3] @ c) @ _rot_x(np.pi / 2))
    # the camera's "rotated" node is Y-up like OpenSim: OpenSim offsets apply as they are
    cam = vis["/Cameras/default/rotated/<object>"]
    cam.set_property("position", [float(x) for x in dist * back])
    cam.set_property("fov", fov_deg)


def _header(title: str, scale: ColorScale, layout: str, robot, dead: list[str], negative: list[str],
            sweep: str | None) -> str:
    e = _html.escape
    fmt = (lambda v: f"{v:.0f}") if scale.quantity == "force" else (lambda v: f"{v:.2f}")
    where = "human left, robot right" if layout == "side" else "human muscles and robot PAMs on one skeleton"
    bar = (f'<span style="display:inline-block;vertical-align:middle;width:160px;height:10px;'
           f'background:{scale.css_gradient()};border:1px solid #888"></span>')
    dead_css = _css(DEAD_ZONE_COLOR)

    def short(names: list[str]) -> str:
        keys = sorted({n.rsplit("_", 1)[0] for n in names})
        return ", ".join(keys[:10]) + (" ..." if len(keys) > 10 else "")

    blocks = {int(t): [robot.names[k] for k in range(len(robot.names)) if robot.transmission[k] == t]
              for t in sorted(set(robot.transmission.tolist())) if t != 1}
    flags = []
    if dead:
        flags.append(f"in a dead zone{' during the sweep' if sweep else ''}: {short(dead)}")
    if negative:
        flags.append(f"PAM longer than its route (negative tendon), drawn clipped: {short(negative)}")
    for t, names in blocks.items():
        flags.append(f"on a {t}:1 pulley block (the PAM drawn at its own length, 1/{t} of the route's stroke): "
                     f"{short(names)}")
    if sweep:
        flags.append(f"animation: {sweep} over range of motion {robot.design.rom} ('Open Controls' to pause or scrub)")
    lines = [
        f"<b>{e(title)}</b> ({e(where)})",
        (f"{e(scale.label)}: {fmt(scale.vmin)} {bar} {fmt(scale.vmax)} &nbsp; "
         f'<span style="color:{dead_css}">&#9632;</span> PAM in a dead zone (strain outside Festo\'s range)'),
        e("Thin: human muscles (full activation); thick: PAMs (Festo nominal diameter); dark grey: fittings and "
          "artificial tendon. " + "; ".join(flags)),
    ]
    return "".join(f'<div class="pamkin-line" title="{e(_strip_tags(x))}">{x}</div>' for x in lines)


def _strip_tags(text: str) -> str:
    import re  # noqa: PLC0415

    return _html.unescape(re.sub(r"<[^>]+>", "", text))


# ----------------------------------------------------------------------------- screenshots
def chromium_command(html: str | os.PathLike, png: str | os.PathLike, user_data_dir: str | os.PathLike,
                     size: tuple[int, int] = (1000, 700), budget_ms: int = 5000,
                     chromium: str = CHROMIUM) -> list[str]:
    """The headless-Chromium command line that renders ``html`` into ``png``.

    WebGL runs in software (SwiftShader); the networking flags keep Chromium from stalling on
    network access; the page's console goes to stderr (``CONSOLE`` lines).
    """
    return [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
            "--disable-quic", "--no-first-run", "--disable-background-networking", "--disable-component-update",
            "--disable-sync", "--hide-scrollbars", "--enable-logging=stderr", "--v=0",
            f"--user-data-dir={user_data_dir}", f"--window-size={size[0]},{size[1]}",
            f"--virtual-time-budget={budget_ms}", f"--screenshot={Path(png).resolve()}",
            Path(html).resolve().as_uri()]


def screenshot(html: str | os.PathLike, png: str | os.PathLike, size: tuple[int, int] = (1000, 700),
               budget_ms: int = 5000, chromium: str = CHROMIUM, timeout: float = 120.0) -> Path:
    """Render a page with headless Chromium (a fresh profile) into a PNG file.

    Raises:
        pamkin.errors.PamkinError: Chromium is missing, fails, or the page raises a JavaScript error.
    """
    exe = chromium if Path(chromium).exists() else shutil.which(Path(chromium).name)
    if not exe:
        raise PamkinError(f"{chromium} not found: install Chromium (Debian: apt-get install -y chromium)")
    png = Path(png)
    png.unlink(missing_ok=True)
    with tempfile.TemporaryDirectory(prefix="pamkin-chromium-") as profile:
        cmd = chromium_command(html, png, profile, size, budget_ms, exe)
        try:
            res = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, check=False)
        except subprocess.TimeoutExpired:
            raise PamkinError(f"chromium did not finish within {timeout:.0f} s rendering {html}") from None
    if res.returncode != 0 or not png.is_file():
        raise PamkinError(f"chromium failed rendering {html} (exit {res.returncode}): {res.stderr.strip()[-500:]}")
    errors = [line for line in res.stderr.splitlines() if "CONSOLE" in line and "Uncaught" in line]
    if errors:
        raise PamkinError(f"{html}: JavaScript error: {errors[0]}")
    return png
