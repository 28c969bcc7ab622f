"""The Crazyflie export read by a third party: Bitcraze's cflib, the library under Crazyswarm2's
Python backend (crazyflie_server_py) and the firmware's high-level commander uploads.

The path a Crazyswarm2 upload takes with its cflib backend is followed with cflib's own code: each
row of ``cf_<i>.csv`` becomes a ``cflib.crazyflie.mem.Poly4D`` (as ``crazyflie_py``'s
``uploadTrajectory`` message and the backend's ``_upload_trajectory_callback`` build it), cflib packs
the pieces (``TrajectoryMemory.write_data``) and sends them in CRTP memory-write packets
(``Memory.write``: 24-byte chunks, each acknowledged), then defines the trajectory
(``HighLevelCommander.define_trajectory``). The other end is a stand-in for the firmware: it stores
the chunks in a 4096-byte trajectory memory (``TRAJECTORY_MEMORY_SIZE``), refuses a write past its
end, acknowledges as the firmware does, and reads the defined trajectory back as ``struct poly4d``
pieces (``float p[4][8]; float duration``, packed: 132 bytes), which are evaluated with
numpy.polynomial and compared with the recorded (flown) path. What this cannot check: ROS 2, the
radio, and the firmware's own evaluation and controllers."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from swarmscene import api
from swarmscene.views import export, plots

cflib_mem = pytest.importorskip("cflib.crazyflie.mem", reason="cflib is in the test extra")
from cflib.crazyflie.high_level_commander import HighLevelCommander  # noqa: E402
from cflib.crtp.crtpstack import CRTPPacket, CRTPPort  # noqa: E402

TRAJECTORY_MEMORY_SIZE = 4096  # crtp_commander_high_level.h
POLY4D = struct.Struct("<32ff")  # struct poly4d: float p[4][8]; float duration (packed)
MEM_ID = 3
CHAN_WRITE = 2  # the memory port's write channel (cflib.crazyflie.mem, the firmware's mem.c)


class FirmwareStandIn:
    """The Crazyflie's side of the link: the trajectory memory, its write acknowledgements, and the
    high-level commander's trajectory definitions."""

    def __init__(self):
        self.memory = bytearray(TRAJECTORY_MEMORY_SIZE)
        self.outbox, self.defined, self.port_callbacks = [], {}, {}
        self.disconnected = type("Caller", (), {"add_callback": lambda _self, cb: None})()

    # -- the cflib Crazyflie object's interface that Memory and HighLevelCommander use --
    def add_port_callback(self, port, callback):
        self.port_callbacks[port] = callback

    def send_packet(self, pk, expected_reply=(), timeout=0.2):
        self.outbox.append(pk)

    # -- the firmware --
    def receive(self, pk):
        """Handle one packet from cflib; the acknowledgement of a memory write goes back to it."""
        if pk.port == CRTPPort.MEM and pk.channel == CHAN_WRITE:
            mem_id, addr = struct.unpack("<BI", bytes(pk.data[:5]))
            chunk = bytes(pk.data[5:])
            ok = mem_id == MEM_ID and addr + len(chunk) <= TRAJECTORY_MEMORY_SIZE  # handleMemWrite's bound
            if ok:
                self.memory[addr:addr + len(chunk)] = chunk
            reply = CRTPPacket()
            reply.set_header(CRTPPort.MEM, CHAN_WRITE)
            reply.data = struct.pack("<BIB", mem_id, addr, 0 if ok else 5)  # 5: EIO
            self.port_callbacks[CRTPPort.MEM](reply)
        elif pk.port == CRTPPort.SETPOINT_HL:
            command, trajectory_id, location, kind, offset, pieces = struct.unpack("<BBBBIB", bytes(pk.data))
            assert (command, location, kind) == (HighLevelCommander.COMMAND_DEFINE_TRAJECTORY,
                                                 HighLevelCommander.TRAJECTORY_LOCATION_MEM,
                                                 HighLevelCommander.TRAJECTORY_TYPE_POLY4D)
            self.defined[trajectory_id] = (offset, pieces)

    def pump(self):
        while self.outbox:
            self.receive(self.outbox.pop(0))

    def trajectory(self, trajectory_id):
        """(durations (P,), coefficients (P, 4, 8)) of a defined trajectory, read from the memory."""
        offset, pieces = self.defined[trajectory_id]
        rows = [POLY4D.unpack_from(self.memory, offset + k * POLY4D.size) for k in range(pieces)]
        return np.array([r[32] for r in rows]), np.array([r[:32] for r in rows]).reshape(-1, 4, 8)


def cflib_pieces(csv_path):
    """The CSV's rows as cflib Poly4D pieces, as Crazyswarm2's cflib backend builds them."""
    data = np.loadtxt(csv_path, delimiter=",", skiprows=1, usecols=range(33), ndmin=2)
    Poly = cflib_mem.Poly4D.Poly
    return [cflib_mem.Poly4D(float(row[0]), Poly(row[1:9].tolist()), Poly(row[9:17].tolist()),
                             Poly(row[17:25].tolist()), Poly(row[25:33].tolist())) for row in data]


def upload(pieces):
    """Upload with cflib's Memory / TrajectoryMemory and define trajectory 0; the firmware stand-in
    and whether cflib reported the write done."""
    firmware = FirmwareStandIn()
    memory = cflib_mem.Memory(firmware)
    trajectory_memory = cflib_mem.TrajectoryMemory(MEM_ID, cflib_mem.MemoryElement.TYPE_TRAJ,
                                                   TRAJECTORY_MEMORY_SIZE, memory)
    memory.mem_write_cb.add_callback(trajectory_memory.write_done)  # as Memory does for a found memory
    memory.mem_write_failed_cb.add_callback(trajectory_memory.write_failed)
    outcome = []
    trajectory_memory.trajectory = pieces
    sent = trajectory_memory.write_data(lambda mem, addr: outcome.append("done"),
                                        lambda mem, addr: outcome.append("failed"))
    firmware.pump()
    if outcome == ["done"]:
        HighLevelCommander(firmware).define_trajectory(0, 0, len(pieces))
        firmware.pump()
    return firmware, sent, outcome


def evaluate(durations, coeffs, t):
    """x, y, z, yaw (T, 4) at times t from the start, each piece by numpy.polynomial."""
    starts = np.concatenate([[0.0], np.cumsum(durations)[:-1]])
    piece = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(durations) - 1)
    out = np.empty((len(t), 4))
    for k in np.unique(piece):
        rows = piece == k
        tau = np.clip(t[rows] - starts[k], 0.0, durations[k])
        out[rows] = np.stack([np.polynomial.polynomial.polyval(tau, coeffs[k, a]) for a in range(4)], axis=1)
    return out


@pytest.fixture(scope="module")
def flown_show(tmp_path_factory):
    """12 s of the VRB air show simulated (the quadrotors' recorded path), exported with --source
    flown: the fit of the path the simulated vehicles flew."""
    run_dir = tmp_path_factory.mktemp("run")
    sim = api.build(["scenario=vrb_airshow", "clock.duration=12.0"])
    api.write_outputs(sim, sim.run(), run_dir)
    out = tmp_path_factory.mktemp("cf")
    export.main([str(run_dir), "--crazyflie", str(out), "--source", "flown"])
    return plots.load_run(run_dir), out


def test_cflib_uploads_each_trajectory_and_the_firmware_layout_gives_back_the_flown_path(flown_show):
    run, out = flown_show
    assert run.n == 3
    for i in range(run.n):
        pieces = cflib_pieces(out / f"cf_{i}.csv")
        firmware, sent, outcome = upload(pieces)
        assert outcome == ["done"]
        assert sent == len(pieces) * export.PIECE_BYTES <= TRAJECTORY_MEMORY_SIZE and len(pieces) > 1
        assert firmware.defined == {0: (0, len(pieces))}
        durations, coeffs = firmware.trajectory(0)
        ours = export.Poly4D.from_csv(out / f"cf_{i}.csv")
        # the bytes in the vehicle are our float32 numbers, bit for bit
        np.testing.assert_array_equal(durations, ours.durations.astype(np.float32))
        np.testing.assert_array_equal(coeffs, ours.coeffs.astype(np.float32))
        # evaluated as the commander does (time from the trajectory's start), within the fit's 5 mm
        flown = evaluate(durations.astype(float), coeffs.astype(float), np.asarray(run.t, float))
        error = np.abs(flown[:, :3] - run.pos[:, i]).max()
        assert error < 0.005, (i, error)
        assert durations.sum() == pytest.approx(run.t[-1], abs=1e-5)


def test_the_firmware_stand_in_refuses_a_trajectory_beyond_its_memory(flown_show):
    """32 pieces (4224 bytes) do not fit the 4096 bytes: the upload fails, as on the vehicle, which
    is why the export stops at 31 pieces."""
    _, out = flown_show
    piece = cflib_pieces(out / "cf_0.csv")[0]
    _, sent, outcome = upload([piece] * (export.MAX_PIECES + 1))
    assert sent == 32 * 132 and outcome == ["failed"]
    _, _, outcome = upload([piece] * export.MAX_PIECES)
    assert outcome == ["done"]
