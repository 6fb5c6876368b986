"""The CiA 402 power state machine: the drive side (controlword -> state -> statusword) and the master
side (statusword -> state, the controlword that moves a drive one step towards a wanted state).

Pure: no bus, no clock. The emulator (hwsim) runs ``DriveStateMachine`` in each node; the robot driver
decodes statuswords and picks controlwords with the functions below. Values follow CiA 402 and the
PRBT facts sheet (section 4.2): statusword states under mask 0x006F, controlword commands by their
bit masks, bit 7 fault reset on its rising edge, bit 8 halt, bit 4 "enable IP mode" in mode 7.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass


class State(enum.Enum):
    NOT_READY = "not_ready_to_switch_on"
    SWITCH_ON_DISABLED = "switch_on_disabled"
    READY_TO_SWITCH_ON = "ready_to_switch_on"
    SWITCHED_ON = "switched_on"
    OPERATION_ENABLED = "operation_enabled"
    QUICK_STOP_ACTIVE = "quick_stop_active"
    FAULT_REACTION_ACTIVE = "fault_reaction_active"
    FAULT = "fault"


# statusword bits 6, 5, 3, 2, 1, 0 of each state (mask 0x006F; bit 5 "quick stop" is 1 when NOT stopping)
_STATE_BITS = {
    State.NOT_READY: 0x0000,
    State.SWITCH_ON_DISABLED: 0x0040,
    State.READY_TO_SWITCH_ON: 0x0021,
    State.SWITCHED_ON: 0x0023,
    State.OPERATION_ENABLED: 0x0027,
    State.QUICK_STOP_ACTIVE: 0x0007,
    State.FAULT_REACTION_ACTIVE: 0x000F,
    State.FAULT: 0x0008,
}
SW_VOLTAGE_ENABLED, SW_WARNING, SW_REMOTE = 0x0010, 0x0080, 0x0200
SW_TARGET_REACHED, SW_INTERNAL_LIMIT, SW_IP_ACTIVE = 0x0400, 0x0800, 0x1000

CW_SWITCH_ON, CW_ENABLE_VOLTAGE, CW_QUICK_STOP_N, CW_ENABLE_OPERATION = 0x0001, 0x0002, 0x0004, 0x0008
CW_ENABLE_IP, CW_FAULT_RESET, CW_HALT = 0x0010, 0x0080, 0x0100

SHUTDOWN, SWITCH_ON, ENABLE_OPERATION, DISABLE_VOLTAGE, QUICK_STOP, DISABLE_OPERATION = (
    0x0006, 0x0007, 0x000F, 0x0000, 0x0002, 0x0007)


class Command(enum.Enum):
    SHUTDOWN = "shutdown"
    SWITCH_ON = "switch_on"
    ENABLE_OPERATION = "enable_operation"
    DISABLE_OPERATION = "disable_operation"
    DISABLE_VOLTAGE = "disable_voltage"
    QUICK_STOP = "quick_stop"
    NONE = "none"


def decode_command(controlword: int) -> Command:
    """The state command of a controlword (CiA 402 table 48; bit 7, bit 8 and bits 4-6 aside)."""
    cw = controlword & 0x008F
    if cw & 0x80:
        return Command.NONE                      # fault reset is an edge, handled separately
    if (cw & 0x02) == 0:
        return Command.DISABLE_VOLTAGE
    if (cw & 0x06) == 0x02:
        return Command.QUICK_STOP
    if (cw & 0x07) == 0x06:
        return Command.SHUTDOWN
    if (cw & 0x0F) == 0x07:
        return Command.SWITCH_ON                 # also "disable operation" from operation enabled
    if (cw & 0x0F) == 0x0F:
        return Command.ENABLE_OPERATION
    return Command.NONE


def state_from_statusword(statusword: int) -> State:
    """Decode a statusword as ros_canopen does (bits 0, 1, 2, 3, 5, 6)."""
    sw = statusword & 0x006F
    if sw & 0x004F == 0x0040:
        return State.SWITCH_ON_DISABLED
    if sw & 0x004F == 0x0000:
        return State.NOT_READY
    if sw & 0x004F == 0x0008:
        return State.FAULT
    if sw & 0x004F == 0x000F:
        return State.FAULT_REACTION_ACTIVE
    for state in (State.READY_TO_SWITCH_ON, State.SWITCHED_ON, State.OPERATION_ENABLED, State.QUICK_STOP_ACTIVE):
        if sw == _STATE_BITS[state]:
            return state
    return State.NOT_READY


@dataclass
class DriveStateMachine:
    """One drive's power state machine. ``on_controlword`` applies a controlword; ``fault`` enters fault
    reaction; ``motion_stopped`` finishes a fault reaction (to FAULT). Transitions that need no command
    (not ready -> switch on disabled after boot) happen in ``boot``."""

    state: State = State.NOT_READY
    _last_cw: int = 0

    def boot(self) -> None:
        self.state = State.SWITCH_ON_DISABLED

    def fault(self) -> None:
        if self.state not in (State.FAULT, State.FAULT_REACTION_ACTIVE):
            self.state = State.FAULT_REACTION_ACTIVE

    def motion_stopped(self) -> None:
        if self.state is State.FAULT_REACTION_ACTIVE:
            self.state = State.FAULT

    def on_controlword(self, controlword: int) -> State:
        rising_reset = bool(controlword & CW_FAULT_RESET) and not (self._last_cw & CW_FAULT_RESET)
        self._last_cw = controlword
        s = self.state
        if s is State.FAULT:
            if rising_reset:
                self.state = State.SWITCH_ON_DISABLED
            return self.state
        if s in (State.FAULT_REACTION_ACTIVE, State.NOT_READY):
            return s
        cmd = decode_command(controlword)
        self.state = _TRANSITIONS.get(s, {}).get(cmd, s)
        return self.state


# the state machine's transitions on a command (CiA 402 Fig. 4; a command not listed leaves the state)
_TRANSITIONS = {
    State.SWITCH_ON_DISABLED: {Command.SHUTDOWN: State.READY_TO_SWITCH_ON},
    State.READY_TO_SWITCH_ON: {Command.SWITCH_ON: State.SWITCHED_ON, Command.ENABLE_OPERATION: State.SWITCHED_ON,
                               Command.DISABLE_VOLTAGE: State.SWITCH_ON_DISABLED,
                               Command.QUICK_STOP: State.SWITCH_ON_DISABLED},
    State.SWITCHED_ON: {Command.ENABLE_OPERATION: State.OPERATION_ENABLED,
                        Command.SHUTDOWN: State.READY_TO_SWITCH_ON,
                        Command.DISABLE_VOLTAGE: State.SWITCH_ON_DISABLED,
                        Command.QUICK_STOP: State.SWITCH_ON_DISABLED},
    State.OPERATION_ENABLED: {Command.SWITCH_ON: State.SWITCHED_ON, Command.SHUTDOWN: State.READY_TO_SWITCH_ON,
                              Command.DISABLE_VOLTAGE: State.SWITCH_ON_DISABLED,
                              Command.QUICK_STOP: State.QUICK_STOP_ACTIVE},
    State.QUICK_STOP_ACTIVE: {Command.DISABLE_VOLTAGE: State.SWITCH_ON_DISABLED,
                              Command.ENABLE_OPERATION: State.OPERATION_ENABLED},
}


def statusword(state: State, ip_active: bool = False, target_reached: bool = False,
               internal_limit: bool = False, warning: bool = False) -> int:
    """The statusword a drive sends in a state (remote bit always; voltage-enabled when powered)."""
    sw = _STATE_BITS[state] | SW_REMOTE
    if state not in (State.NOT_READY, State.SWITCH_ON_DISABLED, State.FAULT):
        sw |= SW_VOLTAGE_ENABLED
    if ip_active:
        sw |= SW_IP_ACTIVE
    if target_reached:
        sw |= SW_TARGET_REACHED
    if internal_limit:
        sw |= SW_INTERNAL_LIMIT
    if warning:
        sw |= SW_WARNING
    return sw


def next_controlword(state: State, want: State, ip_running: bool = True, reset_phase: bool = False) -> int:
    """The controlword that moves a drive in `state` one transition towards `want` (master side).

    want = OPERATION_ENABLED walks switch on disabled -> ready -> switched on -> enabled, with a fault reset
    edge out of FAULT (reset_phase: send bit 7 this cycle; the caller alternates so the drive sees an
    edge). want = QUICK_STOP_ACTIVE sends quick stop; anything else shuts down. In operation enabled with
    IP running the steady word is 0x001F (IP enable, no halt); otherwise halt (bit 8) is set."""
    if want is State.QUICK_STOP_ACTIVE:
        return QUICK_STOP | (CW_ENABLE_IP if ip_running else 0)
    if state is State.FAULT:
        return CW_FAULT_RESET if reset_phase else 0x0000
    if want is not State.OPERATION_ENABLED:
        return SHUTDOWN | CW_HALT
    if state in (State.SWITCH_ON_DISABLED, State.NOT_READY):
        return SHUTDOWN | CW_HALT
    if state is State.READY_TO_SWITCH_ON:
        return SWITCH_ON | CW_HALT
    if state in (State.SWITCHED_ON, State.QUICK_STOP_ACTIVE):
        return ENABLE_OPERATION | CW_HALT
    return (ENABLE_OPERATION | CW_ENABLE_IP) if ip_running else (ENABLE_OPERATION | CW_HALT)
