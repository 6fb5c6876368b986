"""The static cell: floor, boxes (tables, fixtures) and capsules (posts, cables), from a YAML file.

    schema: hrc-scene/1
    floor: {z: 0.0}                    # optional: everything below z is solid
    boxes:                             # axis-aligned in the robot base frame
      - {name: table, center: [x, y, z], size: [sx, sy, sz]}
    capsules:
      - {name: post, a: [x, y, z], b: [x, y, z], radius: r}

Units: metres, robot base frame. A malformed file raises ConfigError naming the entry and field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from shared.core.errors import ConfigError

SCHEMA = "hrc-scene/1"
# the shipped cell: the planner service, `hrc` and the benchmarks read it unless told another file
DEFAULT_SCENE = Path(__file__).resolve().parents[2] / "deploy" / "scene.yaml"


@dataclass(frozen=True)
class Scene:
    """floor_z: height of the floor (-inf: none). box_centers / box_half_sizes: (B, 3).
    capsule_segments (C, 2, 3) and capsule_radii (C,). names: one per box, then one per capsule."""

    floor_z: float = -math.inf
    box_centers: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    box_half_sizes: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    capsule_segments: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 3)))
    capsule_radii: np.ndarray = field(default_factory=lambda: np.zeros(0))
    names: tuple[str, ...] = ()


def _vec(raw, where: str, positive: bool = False) -> np.ndarray:
    if not isinstance(raw, (list, tuple)) or len(raw) != 3 or any(
            isinstance(v, bool) or not isinstance(v, (int, float)) for v in raw):
        raise ConfigError(f"{where}: expected a list of 3 numbers, got {raw!r}")
    v = np.asarray(raw, dtype=float)
    if not np.all(np.isfinite(v)):
        raise ConfigError(f"{where}: numbers must be finite, got {raw!r}")
    if positive and np.any(v <= 0):
        raise ConfigError(f"{where}: sizes must be positive, got {raw!r}")
    return v


def _number(raw, where: str, positive: bool = False) -> float:
    if isinstance(raw, bool) or not isinstance(raw, (int, float)) or not math.isfinite(raw):
        raise ConfigError(f"{where}: expected a finite number, got {raw!r}")
    if positive and raw <= 0:
        raise ConfigError(f"{where}: must be positive, got {raw!r}")
    return float(raw)


def scene_from_mapping(doc: object, where: str = "scene") -> Scene:
    """Validate a parsed scene document."""
    if doc is None:
        return Scene()
    if not isinstance(doc, dict):
        raise ConfigError(f"{where}: expected a mapping, got {type(doc).__name__}")
    unknown = sorted(set(map(str, doc)) - {"schema", "floor", "boxes", "capsules"})
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {unknown}")
    if doc.get("schema", SCHEMA) != SCHEMA:
        raise ConfigError(f"{where}.schema: expected {SCHEMA!r}, got {doc.get('schema')!r}")
    floor = doc.get("floor")
    floor_z = -math.inf
    if floor is not None:
        if not isinstance(floor, dict) or set(floor) != {"z"}:
            raise ConfigError(f"{where}.floor: expected {{z: height}}")
        floor_z = _number(floor["z"], f"{where}.floor.z")
    names, centers, halves, segs, radii = [], [], [], [], []
    for kind in ("boxes", "capsules"):
        entries = doc.get(kind) or []
        if not isinstance(entries, list):
            raise ConfigError(f"{where}.{kind}: expected a list")
        for i, e in enumerate(entries):
            w = f"{where}.{kind}[{i}]"
            if not isinstance(e, dict):
                raise ConfigError(f"{w}: expected a mapping")
            name = str(e.get("name", f"{kind}{i}"))
            need = {"center", "size"} if kind == "boxes" else {"a", "b", "radius"}
            missing, extra = need - set(e), set(e) - need - {"name"}
            if missing or extra:
                raise ConfigError(f"{w} ({name}): needs {sorted(need)}; missing {sorted(missing)}, unknown {sorted(extra)}")
            names.append(name)
            if kind == "boxes":
                centers.append(_vec(e["center"], f"{w}.center"))
                halves.append(_vec(e["size"], f"{w}.size", positive=True) / 2)
            else:
                segs.append([_vec(e["a"], f"{w}.a"), _vec(e["b"], f"{w}.b")])
                radii.append(_number(e["radius"], f"{w}.radius", positive=True))
    return Scene(floor_z, np.array(centers).reshape(-1, 3), np.array(halves).reshape(-1, 3),
                 np.array(segs).reshape(-1, 2, 3), np.array(radii, dtype=float), tuple(names))


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file."""
    path = Path(path)
    try:
        doc = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read scene: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not a text file ({exc.reason} at byte {exc.start})") from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML: {exc}") from None
    return scene_from_mapping(doc, str(path))
