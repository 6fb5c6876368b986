"""The byte layout of a mapped PDO, read once from canopen's PDO map, so a frame is packed or unpacked with
one ``struct`` call.

canopen encodes and decodes a PDO variable by variable through the object dictionary (tens of
microseconds a frame); at 19 frames every 10 ms, in the driver and in the emulator, that was the largest
share of their CPU. The mapping itself still comes from canopen (read from the EDS or over SDO), so a
remapped PDO gets a new layout, never a stale one.
"""

from __future__ import annotations

import struct
from collections.abc import Mapping
from dataclasses import dataclass

from canopen.objectdictionary import ODVariable

from shared.core.errors import HrcError

Key = tuple[int, int]            # (index, subindex) of a mapped object


class PdoLayoutError(HrcError):
    """A PDO mapping this fast path does not handle (not whole bytes, not a fixed-size type)."""


@dataclass(frozen=True)
class PdoLayout:
    """Where each mapped object sits in one PDO's data, little-endian as CANopen sends it."""

    cob_id: int
    keys: tuple[Key, ...]
    frame: struct.Struct

    @classmethod
    def of(cls, pdo_map) -> PdoLayout:
        """The layout of a canopen PdoMap after its mapping was read or saved (dummy gaps are padding)."""
        fmt, keys, offset = "<", [], 0
        for var in pdo_map.map:
            if not var.length:
                continue
            if var.offset % 8 or var.length % 8:
                raise PdoLayoutError(f"PDO 0x{pdo_map.cob_id:X}: 0x{var.index:04X}:{var.subindex} is not byte aligned")
            packer = ODVariable.STRUCT_TYPES.get(var.od.data_type)
            if packer is None or packer.size * 8 != var.length:
                raise PdoLayoutError(f"PDO 0x{pdo_map.cob_id:X}: 0x{var.index:04X}:{var.subindex} has no fixed-size "
                                     "integer or float type of its mapped length")
            fmt += "x" * (var.offset // 8 - offset) + packer.format.lstrip("<>!=@")
            offset = var.offset // 8 + packer.size
            keys.append((var.index, var.subindex))
        return cls(int(pdo_map.cob_id), tuple(keys), struct.Struct(fmt))

    def unpack(self, data: bytes) -> dict[Key, int | float]:
        """The mapped values of a received frame; PdoLayoutError for a frame of another length."""
        if len(data) != self.frame.size:
            raise PdoLayoutError(f"PDO 0x{self.cob_id:X}: {len(data)} bytes, its mapping has {self.frame.size}")
        return dict(zip(self.keys, self.frame.unpack(data)))

    def pack(self, values: Mapping[Key, int | float]) -> bytes:
        """The frame's data from a value per mapped object (a KeyError names one that is missing; a value out
        of its type's range raises struct.error)."""
        return self.frame.pack(*(values[key] for key in self.keys))
