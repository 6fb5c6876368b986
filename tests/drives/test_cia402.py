"""The CiA 402 state machine, drive and master side."""

import pytest

from shared.drives.cia402 import (
    CW_FAULT_RESET,
    Command,
    DriveStateMachine,
    State,
    decode_command,
    next_controlword,
    state_from_statusword,
    statusword,
)


@pytest.mark.parametrize("cw, cmd", [(0x0006, Command.SHUTDOWN), (0x000E, Command.SHUTDOWN), (0x0106, Command.SHUTDOWN),
                                     (0x0007, Command.SWITCH_ON), (0x0107, Command.SWITCH_ON),
                                     (0x000F, Command.ENABLE_OPERATION), (0x001F, Command.ENABLE_OPERATION),
                                     (0x010F, Command.ENABLE_OPERATION), (0x000B, Command.QUICK_STOP),
                                     (0x001B, Command.QUICK_STOP), (0x0002, Command.QUICK_STOP),
                                     (0x0000, Command.DISABLE_VOLTAGE), (0x0080, Command.NONE)])
def test_controlword_decoding(cw, cmd):
    assert decode_command(cw) is cmd


@pytest.mark.parametrize("state", list(State))
def test_statusword_roundtrip(state):
    for extras in ({}, {"ip_active": True, "target_reached": True, "warning": True}):
        assert state_from_statusword(statusword(state, **extras)) is state


def test_facts_sheet_statuswords_decode():
    table = {0x0040: State.SWITCH_ON_DISABLED, 0x0060: State.SWITCH_ON_DISABLED, 0x0021: State.READY_TO_SWITCH_ON,
             0x0023: State.SWITCHED_ON, 0x0027: State.OPERATION_ENABLED, 0x0007: State.QUICK_STOP_ACTIVE,
             0x000F: State.FAULT_REACTION_ACTIVE, 0x002F: State.FAULT_REACTION_ACTIVE, 0x0008: State.FAULT,
             0x0028: State.FAULT, 0x0000: State.NOT_READY}
    for sw, state in table.items():
        assert state_from_statusword(sw | 0x0210) is state


def test_ros_canopen_enable_sequence_reaches_operation_enabled():
    drive = DriveStateMachine()
    drive.boot()
    for cw in (0x0000, 0x0106, 0x0107, 0x010F, 0x001F):
        drive.on_controlword(cw)
    assert drive.state is State.OPERATION_ENABLED


def test_master_walks_a_drive_from_fault_to_enabled():
    drive = DriveStateMachine()
    drive.boot()
    drive.fault()
    drive.motion_stopped()
    assert drive.state is State.FAULT
    phase = False
    for _ in range(10):
        drive.on_controlword(next_controlword(drive.state, State.OPERATION_ENABLED, reset_phase=phase))
        phase = not phase
    assert drive.state is State.OPERATION_ENABLED
    assert next_controlword(State.OPERATION_ENABLED, State.OPERATION_ENABLED) == 0x001F


def test_quick_stop_and_fault_reset_need_an_edge():
    drive = DriveStateMachine(State.OPERATION_ENABLED)
    drive.on_controlword(0x001B)
    assert drive.state is State.QUICK_STOP_ACTIVE
    drive.fault()
    assert drive.state is State.FAULT_REACTION_ACTIVE
    drive.on_controlword(CW_FAULT_RESET)           # ignored until the reaction is over
    drive.motion_stopped()
    drive.on_controlword(CW_FAULT_RESET)           # still high: no rising edge
    assert drive.state is State.FAULT
    drive.on_controlword(0x0000)
    drive.on_controlword(CW_FAULT_RESET)
    assert drive.state is State.SWITCH_ON_DISABLED


def test_operation_enabled_is_unreachable_without_the_sequence():
    drive = DriveStateMachine()
    drive.boot()
    drive.on_controlword(0x000F)
    assert drive.state is State.SWITCH_ON_DISABLED
