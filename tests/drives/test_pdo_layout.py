"""PdoLayout packs and unpacks exactly as canopen's variable-by-variable PDO encoding does."""

from __future__ import annotations

import random

import canopen
import pytest

from shared.drives.pdo_layout import PdoLayout, PdoLayoutError
from shared.drives.prbt import EDS_PATH


def _node() -> canopen.LocalNode:
    node = canopen.LocalNode(3, canopen.import_od(str(EDS_PATH), 3))
    canopen.Network().add_node(node)               # not connected: the PDO maps only need one to subscribe to
    node.rpdo.read(from_od=True)
    node.tpdo.read(from_od=True)
    return node


def _maps(node):
    return [node.rpdo[1], node.tpdo[1], node.tpdo[2], node.tpdo[3]]


def test_pack_and_unpack_match_canopen_for_every_prbt_pdo():
    rng = random.Random(4)
    for pdo_map in _maps(_node()):
        layout = PdoLayout.of(pdo_map)
        assert layout.cob_id == pdo_map.cob_id and layout.keys
        for _ in range(50):
            values = {}
            for var in pdo_map.map:
                if not var.length:
                    continue
                bits = var.length
                signed = var.od.data_type in canopen.objectdictionary.datatypes.SIGNED_TYPES
                lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)
                values[(var.index, var.subindex)] = var.raw = rng.randint(lo, hi)
            assert layout.pack(values) == bytes(pdo_map.data)
            assert layout.unpack(bytes(pdo_map.data)) == values


def test_a_frame_of_the_wrong_length_is_refused():
    layout = PdoLayout.of(_node().tpdo[3])
    with pytest.raises(PdoLayoutError, match="3 bytes"):
        layout.unpack(b"\x00\x01\x02")


def test_a_mapping_not_in_whole_bytes_is_refused():
    pdo_map = _node().tpdo[1]
    pdo_map.map[0].length = 12              # as a bit-mapped PDO would be
    with pytest.raises(PdoLayoutError, match="byte aligned|fixed-size"):
        PdoLayout.of(pdo_map)
