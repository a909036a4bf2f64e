"""OpenSim model → project data file (YAML) → Xacro → URDF.

The importer (:mod:`pamkin.opensim.model_file`) reads the ``.osim``; :func:`model_data` turns it
into the plain numbers the Xacro macros of ``robot/xacro/osim_joint.xacro`` need;
:func:`render_urdf` runs the ``xacro`` Python package on ``robot/osim_model.urdf.xacro``.
Every file is written through :mod:`pamkin.outputs` (atomically).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import yaml

from pamkin._resources import MESH_DIR, ROBOT_DIR, URDF_DIR, cache_dir
from pamkin.errors import BuildError, DataFileError
from pamkin.human.meshes import (
    bone_stl,
    find_geometry_dir,
    mesh_sources,
    stl_name,
    urdf_rpy,
    visual_specs,
)
from pamkin.opensim.functions import LinearFunction
from pamkin.outputs import write_file
from pamkin.opensim.model_file import (
    Coordinate,
    Joint,
    OsimModel,
    TransformAxis,
    _rot,
    load_osim_file,
    model_from_dict,
    model_to_dict,
)
from pamkin.yamlio import safe_load

# ROBOT_DIR (Xacro sources and project data files) and URDF_DIR (generated URDFs) come from
# pamkin._resources: inside the installed package, or the checkout's robot/ and urdf/.
OSIM_XACRO = ROBOT_DIR / "osim_model.urdf.xacro"


def axis_joint_name(joint: Joint, axis: TransformAxis) -> str:
    """URDF joint name of a CustomJoint's variable TransformAxis (``knee_r_translation1``)."""
    return f"{joint.name}_{axis.name}"


def _function_range(axis: TransformAxis, coord: Coordinate | None) -> tuple[float, float]:
    if coord is None:
        v = float(axis.function.value(np.array(0.0)))
        return (v, v)
    lo, hi = coord.range
    vals = axis.function.value(np.linspace(lo, hi, 201))
    return (float(np.min(vals)), float(np.max(vals)))


def _vec(v) -> list[float]:
    """Three floats (Xacro prints each with full precision)."""
    return [float(x) for x in v]


def _axis_specs(joint: Joint, coords: dict[str, Coordinate]) -> list[dict]:
    """Ordered URDF joint specs for one OpenSim joint (translations, then rotations)."""

    order = [a for a in joint.axes if not a.is_rotation] + [a for a in joint.axes if a.is_rotation]
    specs = []
    for a in order:
        zero = {"xyz": [0.0, 0.0, 0.0], "rpy": [0.0, 0.0, 0.0], "axis": _vec(a.axis),
                "coordinate": a.coordinates[0] if a.coordinates else "",
                "identity": isinstance(a.function, LinearFunction) and a.function.slope == 1.0
                and a.function.intercept == 0.0}
        if a.function.is_constant:
            c = float(a.function.value(np.array(0.0)))
            if c == 0.0:
                continue
            spec = dict(zero, name=a.name, type="fixed", lower=0.0, upper=0.0)
            if a.is_rotation:
                spec["rpy"] = _vec(urdf_rpy(_rot(a.axis, c)))
            else:
                spec["xyz"] = _vec([c * v for v in a.axis])
        else:
            lo, hi = _function_range(a, coords.get(a.coordinates[0]) if a.coordinates else None)
            spec = dict(zero, name=a.name, type="revolute" if a.is_rotation else "prismatic",
                        lower=lo, upper=hi)
        specs.append(spec)
    return specs


def urdf_data(model: OsimModel, meshes: Iterable[str] = ()) -> dict:
    """The plain data (bodies, joints as URDF chains) the Xacro macros expand.

    Args:
        model: An imported model.
        meshes: The model's mesh files (``femur_r.vtp``) that are available as STL files beside
            the URDF (see :mod:`pamkin.human.meshes`); each becomes a ``<visual>`` of its body.

    Returns:
        A YAML-serialisable dict: ``bodies`` (name, mass, mass_center, inertia, ``visuals``: mesh
        path relative to the URDF, origin ``xyz``/``rpy`` in the body frame, ``scale``) and
        ``joints`` (name, parent, child, parent offset ``parent_xyz``/``parent_rpy``,
        child-offset inverse ``child_xyz``/``child_rpy``, and ``axes``).
    """

    coords = {c.name: c for c in model.coordinates}
    visuals = visual_specs(model, meshes)
    bodies = [dict(name=b.name, mass=float(b.mass), mass_center=_vec(b.mass_center),
                   inertia=[float(v) for v in b.inertia], visuals=visuals[b.name]) for b in model.bodies]
    joints = []
    for j in model.joints:
        Tp = j.parent_frame.transform()
        Tc_inv = np.linalg.inv(j.child_frame.transform())
        joints.append(dict(
            name=j.name, kind=j.kind, parent=j.parent, child=j.child,
            parent_xyz=_vec(Tp[:3, 3]), parent_rpy=_vec(urdf_rpy(Tp[:3, :3])),
            child_xyz=_vec(Tc_inv[:3, 3]), child_rpy=_vec(urdf_rpy(Tc_inv[:3, :3])),
            axes=_axis_specs(j, coords),
        ))
    return {"bodies": bodies, "joints": joints}


def model_data(model: OsimModel, meshes: Iterable[str] = ()) -> dict:
    """The project's model data file content: the full model and its URDF chains.

    ``model`` holds the imported model losslessly (bodies, joints with their functions,
    coordinates, muscles with paths and parameters); ``urdf`` the numbers the Xacro
    macros expand.
    """
    return {"model": model_to_dict(model), "urdf": urdf_data(model, meshes)}


def load_model_data(path: str | os.PathLike) -> OsimModel:
    """Read a model data file written by :func:`write_model_data` back into an :class:`OsimModel`."""
    path = Path(path)
    try:
        data = safe_load(path.read_text())
        return model_from_dict(data["model"], path=str(path))
    except FileNotFoundError:
        raise DataFileError(str(path), "file not found") from None
    except (yaml.YAMLError, KeyError, TypeError, ValueError, IndexError) as e:
        raise DataFileError(str(path), f"not a pamkin model data file: {type(e).__name__}: {e}") from None


def write_model_data(model: OsimModel, path: Path, meshes: Iterable[str] = ()) -> Path:
    """Write :func:`model_data` of ``model`` to a YAML file (atomically)."""
    write_file(Path(path), model_data_text(model, meshes))
    return Path(path)


def render_xacro(xacro_file: Path, mappings: dict[str, str], sources: str) -> str:
    """Run Xacro on ``xacro_file`` with ``mappings``; return URDF text with a stable banner."""
    import xacro  # noqa: PLC0415  (imported lazily: slow to import)

    try:
        doc = xacro.process_file(str(xacro_file), mappings=mappings)
    except Exception as e:  # xacro raises its own XacroException and plain errors
        raise BuildError(f"xacro failed on {xacro_file} with {mappings}: {e}") from e
    text = doc.toprettyxml(indent="  ")
    # drop xacro's banner (it names absolute paths) for a stable, reproducible file
    lines = [ln for ln in text.splitlines() if not (ln.startswith("<!-- ") and ln.endswith(" -->")
                                                    and ("xacro" in ln or "=====" in ln or "EDITING" in ln))]
    banner = f"<!-- Generated by pamkin from {sources}. Do not edit: regenerate with `pamkin urdf`. -->"
    return "\n".join(lines[:1] + [banner] + lines[1:]) + "\n"


def render_urdf(data_path: Path, name: str, xacro_file: Path = OSIM_XACRO) -> str:
    """Run Xacro on ``xacro_file`` with the model data file ``data_path``; return the URDF text."""
    return render_xacro(xacro_file, {"data": str(Path(data_path).resolve()), "name": name},
                        f"{Path(xacro_file).name} and {Path(data_path).name}")


ROBOT_XACRO = ROBOT_DIR / "pam_biped.urdf.xacro"
ROBOT_URDF = URDF_DIR / "pam_biped.urdf"


def render_robot_urdf(design_path: Path | None = None, skeleton_path: Path | None = None,
                      rom: str = "robot_thesis") -> str:
    """URDF text of the PAM robot (skeleton + robot joint limits + PAM attachment frames)."""
    design_path = Path(design_path or ROBOT_DIR / "data" / "thesis_design.yaml")
    skeleton_path = Path(skeleton_path or ROBOT_DIR / "data" / "gait2392.yaml")
    return render_xacro(ROBOT_XACRO, {"design": str(design_path.resolve()), "skeleton": str(skeleton_path.resolve()),
                                      "rom": rom},
                        f"{ROBOT_XACRO.name}, {skeleton_path.name}, {design_path.name} and rom.yaml ({rom})")


def build(model: OsimModel, data_path: Path, urdf_path: Path, name: str,
          geometry_dir: str | os.PathLike | None = None, write_meshes: bool = True) -> tuple[str, str, dict]:
    """Write the model data file, the bone meshes and the URDF rendered from them (atomically).

    Args:
        geometry_dir: Folder of the model's ``.vtp`` meshes (None: a URDF without visuals).
        write_meshes: Also write the STL files (``meshes/`` beside the URDF).

    Returns:
        (data file text, URDF text, ``{STL path relative to the URDF: bytes}``).
    """

    sources = mesh_sources(model, geometry_dir)
    meshes = {stl_name(n): bone_stl(src) for n, src in sources.items()}
    data_text = model_data_text(model, sources)
    write_file(Path(data_path), data_text)
    urdf = render_urdf(Path(data_path), name)
    if write_meshes:
        for rel, data in meshes.items():
            write_file(Path(urdf_path).parent / rel, data)
    write_file(Path(urdf_path), urdf)
    return data_text, urdf, meshes


def model_data_text(model: OsimModel, meshes: Iterable[str] = ()) -> str:
    """YAML text of :func:`model_data` with a header naming the source."""
    text = (f"# Generated by pamkin from the OpenSim model {Path(model.path).name} (do not edit;\n"
            "# regenerate with `pamkin urdf`). Model credits are in model.credits.\n")
    return text + yaml.safe_dump(model_data(model, meshes), sort_keys=False, width=120)


#: The built-in Gait2392 model: project data file and generated URDF.
GAIT2392_DATA = ROBOT_DIR / "data" / "gait2392.yaml"
GAIT2392_URDF = URDF_DIR / "gait2392.urdf"


def build_gait2392(osim_path: str | os.PathLike, check: bool = False,
                   geometry_dir: str | os.PathLike | None = None) -> list[Path]:
    """Regenerate ``robot/data/gait2392.yaml``, ``urdf/gait2392.urdf``, ``urdf/pam_biped.urdf`` and
    the bone meshes ``urdf/meshes/*.stl`` from an ``.osim`` and its ``.vtp`` files.

    Args:
        osim_path: OpenSim's ``gait2392_thelen2003muscle.osim``.
        check: Do not write; return the files that are missing, differ (stale) or are left over.
        geometry_dir: The ``.vtp`` folder (default: found beside the model as OpenSim does).

    Returns:
        The files written, or with ``check`` the stale ones.

    Raises:
        pamkin.errors.DataFileError: The model file or its geometry folder is missing.
    """

    osim_path = Path(osim_path)
    if not osim_path.is_file():
        raise DataFileError(str(osim_path), "file not found (pass the Gait2392 model with --osim FILE; it is in "
                                            "opensim-models/Gait2392_Simbody/gait2392_thelen2003muscle.osim)")
    geometry = Path(geometry_dir) if geometry_dir else find_geometry_dir(osim_path)
    if geometry is None or not geometry.is_dir():
        raise DataFileError(str(geometry or osim_path.parent / "Geometry"),
                            "no geometry folder with the model's .vtp bone meshes (pass --geometry DIR)")
    model = load_osim_file(osim_path)
    old_meshes = set(MESH_DIR.glob("*.stl")) if MESH_DIR.is_dir() else set()
    if not check:
        _, _, meshes = build(model, GAIT2392_DATA, GAIT2392_URDF, "gait2392", geometry)
        write_file(ROBOT_URDF, render_robot_urdf())
        new = {GAIT2392_URDF.parent / rel for rel in meshes}
        for f in old_meshes - new:
            f.unlink()
        return [GAIT2392_DATA, GAIT2392_URDF, ROBOT_URDF, *sorted(new)]
    import tempfile as _tf  # noqa: PLC0415

    with _tf.TemporaryDirectory() as tmp:
        data_text, urdf, meshes = build(model, Path(tmp) / GAIT2392_DATA.name, Path(tmp) / GAIT2392_URDF.name,
                                        "gait2392", geometry, write_meshes=False)
        robot = render_robot_urdf(skeleton_path=Path(tmp) / GAIT2392_DATA.name)
    robot = robot.replace(f"{Path(tmp).name}", "")  # the banner names only file names
    stale = []
    for path, text in ((GAIT2392_DATA, data_text), (GAIT2392_URDF, urdf), (ROBOT_URDF, robot)):
        if not path.exists() or path.read_text() != text:
            stale.append(path)
    for rel, data in meshes.items():
        path = GAIT2392_URDF.parent / rel
        if not path.exists() or path.read_bytes() != data:
            stale.append(path)
    stale += sorted(old_meshes - {GAIT2392_URDF.parent / rel for rel in meshes})
    return stale


#: The OpenSim reader's folder (its modules are part of the generated URDFs' cache key).
_OPENSIM_DIR = Path(__file__).resolve().parent.parent / "opensim"


def source_hash() -> str:
    """Hash of the Xacro sources and this module (part of the cache key of generated URDFs)."""
    h = hashlib.sha256()
    for p in sorted(ROBOT_DIR.glob("xacro/*.xacro")) + [OSIM_XACRO, Path(__file__),
                                                          _OPENSIM_DIR / "model_file.py",
                                                          _OPENSIM_DIR / "functions.py",
                                                          Path(__file__).with_name("meshes.py"),
                                                          _OPENSIM_DIR / "vtp.py"]:
        h.update(p.read_bytes())
    return h.hexdigest()[:16]


def cached_urdf(model: OsimModel, geometry_dir: str | os.PathLike | None = None) -> Path:
    """URDF of an imported model (with its bone meshes), built in a content-addressed cache folder.

    The cache is ``$PAMKIN_CACHE`` or ``~/.cache/pamkin``; entries are keyed by the model
    file's content, the Xacro sources and the mesh files used, so an edited model is rebuilt.

    Args:
        geometry_dir: Folder of the model's ``.vtp`` meshes (None: a URDF without visuals).
    """
    import warnings  # noqa: PLC0415


    h = hashlib.sha256(Path(model.path).read_bytes())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")          # warned once, when building
        sources = mesh_sources(model, geometry_dir)
    for name, src in sorted(sources.items()):
        st = src.stat()
        h.update(f"{name}:{src.resolve()}:{st.st_size}:{st.st_mtime_ns}".encode())
    folder = cache_dir() / f"{h.hexdigest()[:16]}-{source_hash()}"
    urdf = folder / "model.urdf"
    if not urdf.exists():
        build(model, folder / "model.yaml", urdf, "model", geometry_dir)
    return urdf
