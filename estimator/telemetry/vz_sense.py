"""Which way up an autopilot sends GLOBAL_POSITION_INT.vz, from the height in the same messages.

MAVLink defines vz positive down; Copter before 3.6 sent it positive up
(:mod:`estimator.telemetry.firmware`). Its firmware text says which, when the reader sees it: a
log cut after the autopilot's boot, or a daemon started after it, does not. Then the message
says it itself: its ``relative_alt`` (mm over home) rises where the vehicle climbs. On pairs of
successive messages at most :data:`MAX_PAIR_GAP_S` apart where the height changes by at least
:data:`MIN_RATE_MPS` and vz is as large, the height rate and vz read positive down agree in
sign when vz is sent positive down. Once :data:`DECIDING_PAIRS` pairs are judged, a share of
:data:`DECIDING_SHARE` either way decides (else the judging goes on): a Copter that sends vz
positive up is read so from then on, after the first seconds of its first climb or descent
read the wrong way. A firmware text, or an ArduCopter's AUTOPILOT_VERSION (the daemon asks for
it), decides whenever it comes, over the height's verdict. Only
ArduPilot ever sent vz positive up: an autopilot whose HEARTBEAT names another stack is read
as MAVLink defines it, and its height is not asked (a forged stream cannot turn its climbs
over).

After a reboot (:meth:`VerticalSense.rebooted`) the height's verdict is kept but judged anew
on the new boot's pairs: the same firmware is read right from its first climb, and one
reflashed to the other convention, that neither tells its version nor was heard at boot, is
turned over once the height shows it. A firmware's own verdict stands until the new firmware
tells its own (its boot text, or its AUTOPILOT_VERSION: the daemon asks after each reboot).
"""

from __future__ import annotations

import math

from estimator.telemetry.firmware import copter_version_vz_up, version_numbers

#: Smallest height rate (and climb rate from vz) a pair of messages is judged on, m/s.
MIN_RATE_MPS = 0.5
#: Successive messages further apart than this (s) are not paired.
MAX_PAIR_GAP_S = 5.0
#: Judged pairs before the height's verdict: on every ArduCopter tlog of ``../shared`` and
#: ``replay/`` the judged pairs agree, or disagree, all of them (up to 421 a flight), and the
#: IRIS+ flights climb for a few seconds only (3 to 133 judged pairs without a firmware text).
DECIDING_PAIRS = 3
#: Share of the judged pairs that must agree (or disagree) for a verdict.
DECIDING_SHARE = 0.8


class VerticalSense:
    """The sign that turns a GLOBAL_POSITION_INT.vz as sent into positive down
    (:attr:`down_sign`): 1 (MAVLink's) until a firmware text or the height says otherwise."""

    def __init__(self) -> None:
        self.down_sign = 1
        #: What decided the sign: "firmware", "autopilot" (not ArduPilot), "height", or None
        #: (not yet: MAVLink's).
        self.decided_by: str | None = None
        #: When the height turned the sign over (found vz sent positive up, or after a reboot
        #: positive down again): a sentence saying so, else None.
        self.note: str | None = None
        #: Every such sentence of the stream, in order, but those a firmware or a HEARTBEAT of
        #: the same boot took back (a reflashed autopilot's boots each have theirs).
        self.notes: list[str] = []
        self._boot_notes_from = 0  # the index in ``notes`` of the current boot's first
        #: (major, minor, patch) of the autopilot's AUTOPILOT_VERSION; None before one.
        self.firmware_version: tuple[int, int, int] | None = None
        self._copter = False  # the HEARTBEAT says ArduCopter
        self._last: tuple[float, float, float] | None = None
        self._agree = self._disagree = 0
        self._rejudge = False  # a height verdict from before a reboot, judged anew

    def firmware(self, vz_up: bool) -> None:
        """The firmware (its text, :func:`copter_vz_up`, or its version) says whether vz is
        sent positive up; saying otherwise than the height did takes back the height's note."""
        self.down_sign = -1 if vz_up else 1
        self.decided_by, self._rejudge = "firmware", False
        if not vz_up:
            self._take_back()

    def heartbeat(self, ardupilot: bool, copter: bool) -> None:
        """The autopilot's HEARTBEAT: whether it names ArduPilot, and ArduCopter (a copter's
        frame type). Only ArduPilot ever sent vz positive up; another stack is read as MAVLink
        defines vz, whatever its height said."""
        self._copter = ardupilot and copter
        if not ardupilot and self.decided_by != "firmware":
            self.down_sign, self.decided_by = 1, "autopilot"
            self._take_back()

    def version(self, flight_sw_version: int) -> None:
        """AUTOPILOT_VERSION's ``flight_sw_version``: kept, and for an ArduCopter (its last
        HEARTBEAT said so) it decides as its firmware text does."""
        version = version_numbers(flight_sw_version)
        if version is None:
            return
        self.firmware_version = version
        if self._copter:
            self.firmware(copter_version_vz_up(version))

    def rebooted(self) -> None:
        """The autopilot rebooted (its clock was confirmed behind the old one): a height
        verdict keeps its sign and is judged anew from the new boot's pairs."""
        self._boot_notes_from = len(self.notes)
        if self.decided_by == "height":
            self._rejudge, self._last = True, None
            self._agree = self._disagree = 0

    def observe(self, time_s: float, vz_sent_mps: float, alt_m: float) -> None:
        """One message: its time (s since boot), vz as sent (m/s) and height over home (m)."""
        if self.decided_by is not None and not self._rejudge:
            return
        last, self._last = self._last, (time_s, vz_sent_mps, alt_m)
        if last is None:
            return
        dt_s = time_s - last[0]
        if not 0.0 < dt_s <= MAX_PAIR_GAP_S:
            return
        rate_mps = (alt_m - last[2]) / dt_s
        climb_mps = -0.5 * (vz_sent_mps + last[1])  # read positive down
        if not (abs(rate_mps) >= MIN_RATE_MPS and abs(climb_mps) >= MIN_RATE_MPS):
            return  # level, or not finite
        if math.copysign(1.0, rate_mps) == math.copysign(1.0, climb_mps):
            self._agree += 1
        else:
            self._disagree += 1
        judged = self._agree + self._disagree
        if judged < DECIDING_PAIRS:
            return
        if self._agree >= DECIDING_SHARE * judged:
            self._decide(1, judged)
        elif self._disagree >= DECIDING_SHARE * judged:
            self._decide(-1, judged)

    def _decide(self, down_sign: int, judged: int) -> None:
        """The height's verdict on ``judged`` pairs: vz times ``down_sign`` is positive down."""
        turned = down_sign != self.down_sign
        self.down_sign, self.decided_by, self._rejudge = down_sign, "height", False
        if not turned:
            return
        if down_sign < 0:
            self.note = (
                f"GLOBAL_POSITION_INT.vz disagrees in sign with the altitude rate on "
                f"{self._disagree} of the first {judged} climbing or descending samples: read "
                "positive up from then on, as a Copter before 3.6 sends it (the telemetry named "
                "no firmware)"
            )
        else:
            self.note = (
                f"after the autopilot's reboot GLOBAL_POSITION_INT.vz agrees in sign with the "
                f"altitude rate on {self._agree} of the first {judged} climbing or descending "
                "samples: read positive down again from then on, as MAVLink defines it (new "
                "firmware that named no version)"
            )
        self.notes.append(self.note)

    def _take_back(self) -> None:
        """The height's word is wrong: no standing note, none of this boot's kept."""
        self.note = None
        del self.notes[self._boot_notes_from :]
