"""The cell configuration: one YAML file, validated section by section.

    cell:    {prefix: hrc/cell1}
    ssm:     ISO/TS 15066 parameters (shared.safety.parameters.SsmParameters)
    scaling: control loop parameters (shared.scaling.parameters.ScalingParameters)
    ros2:    the ROS 2 graph the bridge joins (shared.ros2.parameters.Ros2Parameters)
    planning: the planning layer's decisions (shared.planning.parameters.PlanningParameters)

A missing file section takes the defaults; an unknown section or key, a wrong type, a negative time or a
NaN raises ConfigError naming the field. ``deploy/cell.yaml`` is the shipped configuration.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import yaml

from shared.core.errors import ConfigError, KeyError_
from shared.core.sections import from_mapping
from shared.planning.parameters import PlanningParameters
from shared.ros2.parameters import Ros2Parameters
from shared.safety.parameters import SsmParameters
from shared.scaling.parameters import ScalingParameters
from shared.wire.keys import KeySpace

SECTIONS = ("cell", "ssm", "scaling", "ros2", "planning")


@dataclass(frozen=True)
class CellConfig:
    keys: KeySpace = field(default_factory=KeySpace)
    ssm: SsmParameters = field(default_factory=SsmParameters)
    scaling: ScalingParameters = field(default_factory=ScalingParameters)
    ros2: Ros2Parameters = field(default_factory=Ros2Parameters)
    planning: PlanningParameters = field(default_factory=PlanningParameters)

    @classmethod
    def from_mapping(cls, doc: object, where: str = "config") -> "CellConfig":
        if doc is None:
            return cls()
        if not isinstance(doc, dict):
            raise ConfigError(f"{where}: expected a mapping of sections {SECTIONS}, got {type(doc).__name__}")
        unknown = sorted(set(map(str, doc)) - set(SECTIONS))
        if unknown:
            raise ConfigError(f"{where}: unknown section(s) {unknown}; known: {list(SECTIONS)}")
        cell = doc.get("cell") or {}
        if not isinstance(cell, dict) or set(map(str, cell)) - {"prefix"}:
            raise ConfigError(f"{where}: cell: expected a mapping with only 'prefix'")
        try:
            keys = KeySpace(cell.get("prefix", KeySpace.prefix))
            return cls(keys, SsmParameters.from_mapping(doc.get("ssm")),
                       ScalingParameters.from_mapping(doc.get("scaling")),
                       from_mapping(Ros2Parameters, doc.get("ros2"), "ros2"),
                       from_mapping(PlanningParameters, doc.get("planning"), "planning"))
        except (KeyError_, TypeError) as exc:
            raise ConfigError(f"{where}: {exc}") from None
        except ConfigError as exc:
            raise ConfigError(f"{where}: {exc}") from None


def load_config(path: str | Path | None) -> CellConfig:
    """Read and validate a cell config file; None gives the built-in defaults."""
    if path is None:
        return CellConfig()
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read config: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not a text file ({exc.reason} at byte {exc.start})") from None
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML: {exc}") from None
    return CellConfig.from_mapping(doc, str(path))
