"""An external CANopen master (python-can + python-canopen from PyPI) against our joint node.

`jointctl sim --bus slcan:B --node 5` serves a simulated joint (the firmware core's CANopen
node around the host-sim plant) on one end of a `socat` pty pair; python-can's `slcan`
interface drives the other end, and python-canopen loads the EDS that `jointctl eds` generates.
Nothing here knows our object layout except through that EDS.

Run: JOINTCTL=path/to/jointctl .venv/bin/python -m pytest tests/python/test_interop.py
(the cargo test host-sim/jointctl/tests/can_interop.rs does exactly this).
"""

import os
import random
import shutil
import struct
import subprocess
import tempfile
import threading
import time
from pathlib import Path

import configparser
import contextlib

import can
import canopen
import pytest
from canopen.sdo.exceptions import SdoAbortedError

ROOT = Path(__file__).resolve().parents[2]
NODE = 5
HOST_ID = 0x7F
# the simulated joints move: a plant behind each node
PLANT = ["--plant", str(ROOT / "examples/plants/trunk-right.toml")]


def jointctl() -> str:
    exe = os.environ.get("JOINTCTL")
    if exe:
        return exe
    target = os.environ.get("CARGO_TARGET_DIR", str(ROOT / "target"))
    exe = Path(target) / "debug" / "jointctl"
    assert exe.exists(), f"{exe} missing: `cargo build -p jointctl`, or set JOINTCTL to the binary"
    return str(exe)


def wait_for(pred, timeout, what):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return
        time.sleep(0.02)
    raise AssertionError(f"timed out waiting for {what}")


@contextlib.contextmanager
def served(prefix, eds_args, sim_args):
    """A socat pty pair with `jointctl sim SIM_ARGS` on one end and python-canopen's network
    (python-can's slcan) on the other, and the EDS `jointctl eds EDS_ARGS` writes. Yields
    (network, eds); at the end the sim must stop cleanly on SIGTERM (exit 0)."""
    assert shutil.which("socat"), "socat is needed (apt-get install socat)"
    tmp = Path(tempfile.mkdtemp(prefix=prefix))
    a, b = tmp / "canA", tmp / "canB"
    socat = subprocess.Popen(
        ["socat", "-d", "-d", f"pty,raw,echo=0,link={a}", f"pty,raw,echo=0,link={b}"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    wait_for(lambda: a.exists() and b.exists(), 5, "socat ptys")
    eds = tmp / "joint.eds"
    subprocess.run([jointctl(), "eds", *eds_args, "--out", str(eds)], check=True)
    sim = subprocess.Popen(
        [jointctl(), "sim", "--bus", f"slcan:{b}", *sim_args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    network = canopen.Network()
    network.connect(interface="slcan", channel=str(a), bitrate=1000000)
    try:
        yield network, eds
    finally:
        network.disconnect()
        # SIGTERM stops `jointctl sim` cleanly (exit 0, summary on stderr)
        sim.terminate()
        try:
            rc = sim.wait(timeout=5)
        except subprocess.TimeoutExpired:
            sim.kill()
            rc = "hung"
        socat.terminate()
        socat.wait(timeout=5)
        shutil.rmtree(tmp, ignore_errors=True)
        assert rc == 0, f"jointctl sim {sim_args} did not stop cleanly on SIGTERM: {rc} {sim.stderr.read()!r}"


@contextlib.contextmanager
def joined(network, node_id, eds):
    """The node through its EDS, our heartbeat running (until the block ends), its latched
    heartbeat_lost cleared:
    the joint booted before our heartbeat started, so its watchdog (consumer 0x1016, node
    0x7F) latched heartbeat_lost, which by design stays until the host acknowledges it."""
    node = network.add_node(node_id, str(eds))
    node.sdo.RESPONSE_TIMEOUT = 1.0
    hb = network.send_periodic(0x700 + HOST_ID, bytes([0x05]), 0.05)
    node.nmt.wait_for_heartbeat(timeout=2)
    time.sleep(0.1)
    node.sdo["clear_faults"].raw = 1
    try:
        yield node
    finally:
        hb.stop()


@pytest.fixture(scope="module")
def rig():
    with served("joint-interop-", [], ["--node", str(NODE), *PLANT]) as (network, eds):
        with joined(network, NODE, eds) as node:
            yield network, node, eds


def abort_code(exc_info):
    return exc_info.value.code


def params(node):
    """The manufacturer parameter objects (0x2000..) as the EDS lists them."""
    od = node.object_dictionary
    return [od[i] for i in sorted(od.indices) if 0x2000 <= i < 0x2100]


def f32(x):
    return struct.unpack("<f", struct.pack("<f", x))[0]


def reset_node(network, node, timeout=5.0):
    """NMT reset node, and wait for its boot-up message (0x700 + id, one byte 0). Listening
    starts before the reset is sent: python-canopen's `wait_for_bootup` clears what it heard
    before it is called, so a node that boots before the waiting starts (a loaded host delays
    this thread past the sim's reboot) timed out the test (CI, sixteenth session)."""
    booted = threading.Event()

    def heard(cob, data, ts):
        if bytes(data) == b"\x00":
            booted.set()

    network.subscribe(0x700 + node.id, heard)
    try:
        node.nmt.state = "RESET"
        assert booted.wait(timeout), f"node {node.id} sent no boot-up within {timeout} s of a reset"
    finally:
        network.unsubscribe(0x700 + node.id, heard)


def preop(node):
    node.nmt.state = "PRE-OPERATIONAL"
    time.sleep(0.05)


def commit(node):
    """Commit the staged set by naming it: its CRC-32 to params_commit_crc (0x2205). The joint
    refuses a plain commit (params_commit = 1), which named no set and so made live whatever
    was staged, another master's values too. This master is alone on the bus and has read back
    what it staged, so the staged set's CRC (params_crc.staged_crc, 0x2204:2) names the set it
    means; a master sharing the bus computes the CRC from the set it means (jointctl does)."""
    node.sdo["params_commit_crc"].raw = node.sdo["params_crc"]["staged_crc"].raw


def test_heartbeat_and_boot_state(rig):
    network, node, _ = rig
    state = node.nmt.wait_for_heartbeat(timeout=2)
    assert state in ("PRE-OPERATIONAL", "OPERATIONAL")
    preop(node)
    assert node.nmt.wait_for_heartbeat(timeout=2) == "PRE-OPERATIONAL"
    # producer heartbeat time 0x1017 is writable: 50 ms, then back
    node.sdo[0x1017].raw = 50
    t0 = time.monotonic()
    for _ in range(10):
        node.nmt.wait_for_heartbeat(timeout=1)
    period = (time.monotonic() - t0) / 10
    assert 0.03 < period < 0.09, period
    node.sdo[0x1017].raw = 100


def test_identity_and_strings(rig):
    _, node, _ = rig
    assert node.sdo[0x1000].raw == 0
    assert node.sdo[0x1018][1].raw == 0
    assert node.sdo[0x1018][2].raw == 0x4A4E0001
    assert node.sdo[0x1018][3].raw == 0x00010000
    # segmented upload of a VISIBLE_STRING
    assert node.sdo["manufacturer_device_name"].raw == "joint-node"
    assert node.sdo["manufacturer_software_version"].raw.count(".") == 2


def eds_limits(eds, index):
    """LowLimit/HighLimit of a REAL32 object, read from the EDS text itself (python-canopen
    parses limits as integers only and drops fractional ones such as 1.01)."""
    cp = configparser.ConfigParser()
    cp.read(eds)
    sec = cp[f"{index:04X}"]
    return float(sec["LowLimit"]), float(sec["HighLimit"])


def test_every_manufacturer_object_reads_default_and_writes(rig):
    _, node, eds = rig
    preop(node)
    objs = params(node)
    # one object per entry of the core's parameter table (listed with units in [Comments])
    cp = configparser.ConfigParser()
    cp.read(eds)
    assert len(objs) == int(cp["Comments"]["Lines"]) >= 27, [o.name for o in objs]
    names = {o.name for o in objs}
    for n in ("friction_a", "weight_amplitude", "compensation_fraction", "controller_heartbeat_timeout"):
        assert n in names
    for o in objs:
        assert o.data_type == canopen.objectdictionary.REAL32, o.name
        v = node.sdo[o.name].raw
        assert v == pytest.approx(f32(o.default)), o.name
        lo, hi = eds_limits(eds, o.index)
        assert lo < hi, o.name
        want = f32(lo + 0.25 * (hi - lo))
        node.sdo[o.name].raw = want
        assert node.sdo[o.name].raw == want, o.name
    # staged, not yet running: the pending flag says so; discard them (commit object = 0)
    assert node.sdo["params_pending"].raw == 1
    node.sdo["params_commit"].raw = 0
    assert node.sdo["params_pending"].raw == 0
    for o in objs:
        assert node.sdo[o.name].raw == pytest.approx(f32(o.default)), o.name


def test_process_data_objects_by_sdo(rig):
    _, node, _ = rig
    preop(node)
    # joint state: readable, not writable
    for sub in ("q", "qd", "tau_cmd", "faults", "qdd", "tau_measured", "temperature", "gain_permille"):
        node.sdo["joint_state"][sub].raw
    with pytest.raises(SdoAbortedError) as e:
        node.sdo["joint_state"]["q"].raw = 1
    assert abort_code(e) == 0x06010002
    # other joints' angles: read/write (1e-4 rad per LSB)
    node.sdo["other_joint_angles"][2].raw = -1234
    assert node.sdo["other_joint_angles"][2].raw == -1234
    node.sdo["other_joint_angles"][2].raw = 0
    # the host's assist command only while operational (the torque is off otherwise)
    with pytest.raises(SdoAbortedError) as e:
        node.sdo["host_command"]["assist_cmd"].raw = 150
    assert abort_code(e) == 0x08000022
    node.nmt.state = "OPERATIONAL"
    time.sleep(0.05)
    node.sdo["host_command"]["assist_cmd"].raw = 150
    assert node.sdo["host_command"]["assist_cmd"].raw == 150
    preop(node)
    assert node.sdo["host_command"]["assist_cmd"].raw == 0  # dropped on leaving operational


def test_the_eds_gives_every_process_value_its_scale_and_unit(rig):
    # Issue 21: python-canopen showed q = -734 with no scale anywhere. The EDS now carries the
    # factor and unit of each INTEGER16 value and what the fault bits mean, so .phys is physical.
    _, node, _ = rig
    preop(node)
    od = node.object_dictionary
    want = {"q": (1e-4, "rad"), "qd": (1e-3, "rad/s"), "tau_cmd": (1e-2, "N*m"), "qdd": (1e-2, "rad/s^2"),
            "tau_measured": (1e-2, "N*m"), "temperature": (1e-2, "degC")}
    for sub, (factor, unit) in want.items():
        v = od["joint_state"][sub]
        assert v.factor == pytest.approx(factor), sub
        assert v.unit == unit, sub
    assert "bit 0 heartbeat_lost" in od["joint_state"]["faults"].description
    assert od["friction_c"].unit == "N*m"
    # a physical write: 0.5 rad of another joint's angle goes over the bus as 5000 LSB
    node.sdo["other_joint_angles"][2].phys = 0.5
    assert node.sdo["other_joint_angles"][2].raw == 5000
    assert node.sdo["other_joint_angles"][2].phys == pytest.approx(0.5)
    node.sdo["other_joint_angles"][2].raw = 0


def test_gravity_table_by_segmented_sdo_and_commit(rig):
    _, node, _ = rig
    preop(node)
    grid = [-1.0 + 0.25 * k for k in range(9)]
    torque = [0.5 * k - 1.0 for k in range(9)]
    node.sdo["gravity_table_shape"]["n_axes"].raw = 1
    node.sdo["gravity_table_shape"]["points_0"].raw = 9
    node.sdo["gravity_table_grid"].raw = struct.pack("<9f", *grid)
    node.sdo["gravity_table_torque"].raw = struct.pack("<9f", *torque)
    commit(node)
    assert node.sdo["params_pending"].raw == 0
    back = node.sdo["gravity_table_torque"].raw
    assert struct.unpack("<9f", back) == tuple(f32(x) for x in torque)
    g = node.sdo["gravity_table_grid"].raw
    assert struct.unpack("<9f", g[:36]) == tuple(f32(x) for x in grid)
    # remove it again
    node.sdo["gravity_table_shape"]["n_axes"].raw = 0
    commit(node)


def test_gravity_table_by_block_transfer_with_crc(rig):
    """python-canopen's block download and upload (CRC requested) of a 512-byte table domain."""
    _, node, _ = rig
    preop(node)
    index = node.object_dictionary["gravity_table_torque"].index
    # 2 axes of 16 × 8 points: 128 cells, the largest table (its upload length follows the shape)
    node.sdo["gravity_table_shape"]["n_axes"].raw = 2
    node.sdo["gravity_table_shape"]["points_0"].raw = 16
    node.sdo["gravity_table_shape"]["points_1"].raw = 8
    torque = [0.01 * k - 0.5 for k in range(128)]
    data = struct.pack("<128f", *torque)
    with node.sdo.open(index, 0, "wb", size=len(data), block_transfer=True, request_crc_support=True) as f:
        f.write(data)
    with node.sdo.open(index, 0, "rb", block_transfer=True, request_crc_support=True) as f:
        back = f.read()
    assert back == data
    # the segmented protocol reads the same bytes
    assert node.sdo["gravity_table_torque"].raw == data
    # a block download without CRC, shorter: 9 values
    short = struct.pack("<9f", *torque[:9])
    with node.sdo.open(index, 0, "wb", size=len(short), block_transfer=True, request_crc_support=False) as f:
        f.write(short)
    assert node.sdo["gravity_table_torque"].raw[:36] == short
    # discard the staged changes: nothing of this goes live
    node.sdo["params_commit"].raw = 0
    assert node.sdo["params_pending"].raw == 0


def test_a_second_sdo_channel_serves_another_master_mid_transfer(rig):
    """0x1201 configured through the EDS, then a second python-canopen SdoClient on it reads and
    block-writes while the first channel is in the middle of a segmented upload."""
    network, node, _ = rig
    preop(node)
    assert node.sdo["sdo_server_2"]["cob_id_rx"].raw & 0x80000000
    node.sdo["sdo_server_2"]["cob_id_rx"].raw = 0x640 + NODE
    node.sdo["sdo_server_2"]["cob_id_tx"].raw = 0x5C0 + NODE
    node.sdo["sdo_server_2"]["client_node_id"].raw = 0x7E
    assert node.sdo["sdo_server_1"]["cob_id_rx"].raw == 0x600 + NODE
    sdo2 = node.add_sdo(0x640 + NODE, 0x5C0 + NODE)
    sdo2.network = network  # python-canopen 2.4's add_sdo subscribes but does not attach it
    sdo2.RESPONSE_TIMEOUT = 1.0
    node.sdo["gravity_table_shape"]["n_axes"].raw = 1
    node.sdo["gravity_table_shape"]["points_0"].raw = 9
    # channel 1: a segmented upload of the device name, left open after its first segment
    name = node.object_dictionary["manufacturer_device_name"].index
    stream = node.sdo.open(name, 0, "rb", buffering=0)
    first = stream.read(7)
    # channel 2: a whole expedited read and a block download while channel 1 waits
    product = sdo2.upload(0x1018, 2)
    sigma = node.object_dictionary["gravity_table_sigma"].index
    data = struct.pack("<9f", *[0.125 * k for k in range(9)])
    with sdo2.open(sigma, 0, "wb", size=len(data), block_transfer=True) as f:
        f.write(data)
    # channel 1 carries on where it was
    rest = stream.read()
    stream.close()
    assert first + rest == b"joint-node"
    assert product == node.sdo.upload(0x1018, 2)
    assert node.sdo.upload(sigma, 0) == data
    node.sdo["params_commit"].raw = 0
    node.sdo["sdo_server_2"]["cob_id_rx"].raw = 0x80000000


def test_aborts_keep_the_old_value(rig):
    _, node, _ = rig
    preop(node)
    before = node.sdo["friction_v_band"].raw
    with pytest.raises(SdoAbortedError) as e:
        node.sdo["friction_v_band"].raw = 2.0  # max 1.0
    assert abort_code(e) == 0x06090031
    with pytest.raises(SdoAbortedError) as e:
        node.sdo["friction_a"].raw = -1.0  # min 0
    assert abort_code(e) == 0x06090032
    with pytest.raises(SdoAbortedError) as e:
        node.sdo["friction_a"].raw = float("nan")
    assert abort_code(e) == 0x06090030
    assert node.sdo["friction_v_band"].raw == before
    assert node.sdo["friction_a"].raw == 0.0
    # size: 2 bytes into a REAL32
    with pytest.raises(SdoAbortedError) as e:
        node.sdo.download(0x2000, 0, b"\x00\x00")
    assert abort_code(e) in (0x06070010, 0x06070012, 0x06070013)
    # access
    with pytest.raises(SdoAbortedError) as e:
        node.sdo.download(0x1000, 0, b"\x01\x00\x00\x00")
    assert abort_code(e) == 0x06010002
    with pytest.raises(SdoAbortedError) as e:
        node.sdo.upload(0x2200, 0)
    assert abort_code(e) == 0x06010001
    # existence
    with pytest.raises(SdoAbortedError) as e:
        node.sdo.upload(0x3000, 0)
    assert abort_code(e) == 0x06020000
    with pytest.raises(SdoAbortedError) as e:
        node.sdo.upload(0x1018, 9)
    assert abort_code(e) == 0x06090011
    # device state: a safety-relevant parameter while operational
    frac = node.sdo["compensation_fraction"].raw
    node.nmt.state = "OPERATIONAL"
    time.sleep(0.05)
    with pytest.raises(SdoAbortedError) as e:
        node.sdo["compensation_fraction"].raw = 0.7
    assert abort_code(e) == 0x08000022
    assert node.sdo["compensation_fraction"].raw == frac
    preop(node)
    node.sdo["compensation_fraction"].raw = 0.7
    commit(node)
    assert node.sdo["compensation_fraction"].raw == f32(0.7)
    node.sdo["compensation_fraction"].raw = frac
    commit(node)
    assert node.sdo["params_pending"].raw == 0


def test_refused_commit_names_the_parameter_and_keeps_the_set(rig):
    _, node, _ = rig
    preop(node)
    node.emcy.reset()
    old = node.sdo["controller_accel_cutoff"].raw
    node.sdo["controller_accel_cutoff"].raw = 600.0  # in range, but ≥ half the 1 kHz rate
    with pytest.raises(SdoAbortedError) as e:
        commit(node)
    assert abort_code(e) == 0x06090030
    # the EMCY goes out with the abort; python-canopen logs every EMCY it receives
    wait_for(lambda: any(x.code == 0x6320 for x in node.emcy.log), 2, "EMCY 0x6320")
    err = [x for x in node.emcy.log if x.code == 0x6320][-1]
    assert err.data[0] == 3 and int.from_bytes(err.data[1:3], "little") == 0x16
    msg = node.sdo["params_commit_error"]["message"].raw
    assert msg.startswith("controller_accel_cutoff"), msg
    assert node.sdo["params_commit_error"]["param_index"].raw == 0x16
    # the staged value is still there, the running one is not: discard brings the old back
    assert node.sdo["params_pending"].raw == 1
    node.sdo["params_commit"].raw = 0
    assert node.sdo["controller_accel_cutoff"].raw == old


def test_a_plain_commit_is_refused_and_a_commit_names_its_set(rig):
    """Issue 21: a plain commit made live whatever was staged, so a half-staged set from a
    failed push plus one value from another master went live as a mix. The joint refuses it
    (0x06010000, commit error 9, EMCY 0x6320) and commits only the set a commit names by CRC;
    the EDS says so where python-canopen reads it."""
    _, node, _ = rig
    preop(node)
    od = node.object_dictionary
    assert "refused" in od["params_commit"].description and "0x2205" in od["params_commit"].description
    assert "CRC-32 of the set you mean" in od["params_commit_crc"].description
    active = node.sdo["params_crc"]["active_crc"].raw
    old = node.sdo["friction_c"].raw
    node.sdo["friction_c"].raw = old + 0.5
    node.emcy.reset()
    with pytest.raises(SdoAbortedError) as e:
        node.sdo["params_commit"].raw = 1
    assert abort_code(e) == 0x06010000
    wait_for(lambda: any(x.code == 0x6320 and x.data[0] == 9 for x in node.emcy.log), 2, "EMCY 0x6320, code 9")
    assert node.sdo["params_commit_error"]["code"].raw == 9
    assert "0x2205" in node.sdo["params_commit_error"]["message"].raw
    assert node.sdo["params_crc"]["active_crc"].raw == active, "nothing went live"
    assert node.sdo["params_pending"].raw == 1
    # naming another set (the one in force) is refused too: the staged set is not that set
    with pytest.raises(SdoAbortedError) as e:
        node.sdo["params_commit_crc"].raw = active
    assert abort_code(e) == 0x08000022
    assert node.sdo["params_commit_error"]["code"].raw == 7
    # naming the staged set commits it
    commit(node)
    assert node.sdo["params_pending"].raw == 0
    assert node.sdo["params_crc"]["active_crc"].raw != active
    node.sdo["friction_c"].raw = old
    commit(node)
    assert node.sdo["params_crc"]["active_crc"].raw == active


def test_tpdos_decoded_through_the_eds_mapping(rig):
    network, node, _ = rig
    node.tpdo.read(from_od=True)
    node.nmt.state = "OPERATIONAL"
    tp1 = node.tpdo[1]
    assert [v.name for v in tp1] == ["joint_state." + n for n in ("q", "qd", "tau_cmd", "faults")]
    assert tp1.cob_id == 0x180 + NODE
    stamps = []
    for _ in range(20):
        assert tp1.wait_for_reception(timeout=1.0) is not None
        stamps.append(tp1.timestamp)
    period = (stamps[-1] - stamps[0]) / (len(stamps) - 1)
    assert 0.005 < period < 0.02, period  # event timer 10 ms
    vals = {v.name.split(".")[-1]: v.raw for v in tp1}
    # the plant moves within ±0.5 rad under the simulated operator; raw is 1e-4 rad per LSB
    assert abs(vals["q"]) < 5000, vals
    assert vals["faults"] == 0, vals
    tp2 = node.tpdo[2]
    assert [v.name.split(".")[-1] for v in tp2] == ["qdd", "tau_measured", "temperature", "gain_permille"]
    assert tp2.wait_for_reception(timeout=1.0) is not None
    assert {v.name.split(".")[-1]: v.raw for v in tp2}["temperature"] == 3000  # 30.00 °C
    # event timer is configurable: 20 ms
    node.sdo[0x1800][5].raw = 20
    tp1.wait_for_reception(timeout=1.0)
    t0 = tp1.timestamp
    for _ in range(10):
        tp1.wait_for_reception(timeout=1.0)
    assert 0.015 < (tp1.timestamp - t0) / 10 < 0.03
    node.sdo[0x1800][5].raw = 10
    preop(node)


def test_garbage_frames_leave_the_node_alive_and_unchanged(rig):
    network, node, _ = rig
    preop(node)
    before = {o.name: node.sdo[o.name].raw for o in params(node)}
    node.nmt.state = "OPERATIONAL"
    rng = random.Random(20261122)
    bus = network.bus
    for _ in range(3000):
        # any id but NMT (a well-formed NMT reset is a command, not garbage)
        cob = rng.choice([0x600 + NODE, 0x200 + NODE, 0x700 + HOST_ID, rng.randrange(1, 0x800)])
        data = bytes(rng.randrange(256) for _ in range(rng.randrange(9)))
        bus.send(can.Message(arbitration_id=cob, data=data, is_extended_id=False))
    time.sleep(0.5)
    assert node.nmt.wait_for_heartbeat(timeout=2) == "OPERATIONAL"
    preop(node)
    # discard whatever a random SDO write may have staged, then nothing may differ
    node.sdo["params_commit"].raw = 0
    after = {o.name: node.sdo[o.name].raw for o in params(node)}
    assert after == before
    assert node.sdo[0x1018][2].raw == 0x4A4E0001


def test_sync_triggered_tpdo_and_the_error_history(rig):
    """A master's SYNC drives a synchronous TPDO (transmission type N = every Nth SYNC), the
    SYNC and EMCY COB-IDs read as CiA 301 says, and the error history (0x1003) records an EMCY
    and is cleared by writing 0, all through python-canopen's own SYNC producer and the EDS."""
    network, node, _ = rig
    assert node.sdo[0x1005].raw == 0x80
    assert node.sdo[0x1014].raw == 0x80 + NODE
    assert node.sdo[0x1029][1].raw == 1  # a communication error leaves the NMT state alone
    node.tpdo.read(from_od=True)
    tp1 = node.tpdo[1]
    node.sdo[0x1800][2].raw = 2  # every 2nd SYNC
    node.nmt.state = "OPERATIONAL"
    got = []
    tp1.add_callback(lambda m: got.append(m.timestamp))
    time.sleep(0.3)
    assert got == [], "no SYNC, no synchronous TPDO (its event timer does not drive it)"
    network.sync.start(0.02)  # python-canopen's SYNC producer, 50 Hz
    time.sleep(1.0)
    network.sync.stop()
    time.sleep(0.05)
    n = len(got)
    assert 18 <= n <= 32, n  # ~25 = 50 SYNCs / 2
    period = (got[-1] - got[0]) / (n - 1)
    assert 0.03 < period < 0.05, period
    with pytest.raises(SdoAbortedError) as e:
        node.sdo[0x1800][2].raw = 0  # acyclic synchronous: not served
    assert abort_code(e) == 0x06090030
    node.sdo[0x1800][2].raw = 0xFE
    preop(node)
    # the error history: clear, cause one EMCY (a refused commit), read it back, clear again
    node.sdo[0x1003][0].raw = 0
    assert node.sdo[0x1003][0].raw == 0
    with pytest.raises(SdoAbortedError) as e:
        node.sdo[0x1003][0].raw = 3  # only 0 may be written
    assert abort_code(e) == 0x06090030
    node.emcy.reset()
    old = node.sdo["controller_accel_cutoff"].raw
    node.sdo["controller_accel_cutoff"].raw = 600.0  # in range, but >= half the 1 kHz rate
    with pytest.raises(SdoAbortedError):
        commit(node)
    wait_for(lambda: any(x.code == 0x6320 for x in node.emcy.log), 2, "EMCY 0x6320")
    assert node.sdo[0x1003][0].raw == 1
    assert node.sdo[0x1003][1].raw & 0xFFFF == 0x6320
    node.sdo["params_commit"].raw = 0  # discard the staged set
    assert node.sdo["controller_accel_cutoff"].raw == old
    node.sdo[0x1003][0].raw = 0
    assert node.sdo[0x1003][0].raw == 0


def test_tpdo_remapped_through_the_pdo_api_and_kept_by_store(rig):
    """python-canopen's own PDO configuration (read, clear, add_variable, save: the CiA 301
    disable / sub 0 = 0 / entries / sub 0 = n / enable sequence by SDO), the remapped TPDO
    received and decoded, the mapping stored with 0x1010 and back after an NMT reset node.
    Runs last on this rig: it leaves the defaults restored (0x1011) for a clean teardown."""
    network, node, _ = rig
    preop(node)
    node.tpdo.read()
    tp = node.tpdo[1]
    tp.clear()
    tp.add_variable("joint_state_real32", "q")
    tp.add_variable("joint_state", "faults")
    tp.add_variable(0x1001)
    tp.enabled = True
    tp.save()
    assert [node.sdo[0x1A00][k].raw for k in range(4)] == [3, 0x23010120, 0x23000410, 0x10010008]
    node.nmt.state = "OPERATIONAL"
    assert tp.wait_for_reception(timeout=1.0) is not None
    assert tp.wait_for_reception(timeout=1.0) is not None
    q = tp["joint_state_real32.q"].raw
    assert isinstance(q, float) and abs(q) < 1.0, q  # REAL32 in rad: no scale
    assert tp["joint_state.faults"].raw == 0
    assert len(tp.data) == 7
    preop(node)
    # refused steps name their reason and change nothing
    node.sdo[0x1800][1].raw = 0x80000185
    with pytest.raises(SdoAbortedError) as e:
        node.sdo[0x1A00][1].raw = 0x23010120
    assert abort_code(e) == 0x06010000  # entries are locked while sub 0 is not 0
    node.sdo[0x1A00][0].raw = 0
    with pytest.raises(SdoAbortedError) as e:
        node.sdo[0x1A00][1].raw = 0x20000020  # a parameter object is not mappable
    assert abort_code(e) == 0x06040041
    node.sdo[0x1A00][3].raw = 0x23010220  # q̇: 4 + 2 + 4 = 10 bytes
    with pytest.raises(SdoAbortedError) as e:
        node.sdo[0x1A00][0].raw = 3
    assert abort_code(e) == 0x06040042
    node.sdo[0x1A00][3].raw = 0x10010008
    node.sdo[0x1A00][0].raw = 3
    node.sdo[0x1800][1].raw = 0x185
    # stored with the parameters, back after a reset of the node
    node.store()
    reset_node(network, node)
    time.sleep(0.2)
    node.sdo["clear_faults"].raw = 1
    node.tpdo.read()
    assert [v.name for v in node.tpdo[1]] == ["joint_state_real32.q", "joint_state.faults", "error_register"]
    # 0x1011: the defaults after the next reset
    node.restore()
    reset_node(network, node)
    time.sleep(0.2)
    node.sdo["clear_faults"].raw = 1
    assert node.sdo[0x1A00][0].raw == 4 and node.sdo[0x1A00][1].raw == 0x23000110


# ---- CAN FD ------------------------------------------------------------------------------
# python-can's slcan interface speaks the CANable 2.0 FD extension (`b`/`d` lines, DLC 0..F),
# so the FD joint is reached the same way: `jointctl sim --fd` on one end of a pty pair,
# python-canopen with the FD EDS (`jointctl eds --fd`) on the other.

FD_NODE = 6


@pytest.fixture(scope="module")
def fd_rig():
    with served("joint-interop-fd-", ["--fd"], ["--node", str(FD_NODE), "--fd", *PLANT]) as (network, eds):
        frames = can.BufferedReader()
        network.notifier.add_listener(frames)
        with joined(network, FD_NODE, eds) as node:
            yield network, node, frames


def test_fd_tpdo_carries_the_whole_state_decoded_through_the_eds(fd_rig):
    network, node, frames = fd_rig
    node.tpdo.read(from_od=True)
    tp3 = node.tpdo[3]
    names = [v.name.split(".")[-1] for v in tp3]
    assert names == ["q", "qd", "qdd", "tau_cmd", "tau_measured", "u_motor", "temperature",
                     "faults", "mode", "error_register"], names
    assert tp3.cob_id == 0x380 + FD_NODE
    assert not node.tpdo[1].enabled and not node.tpdo[2].enabled, "classic TPDOs start invalid on FD"
    node.nmt.state = "OPERATIONAL"
    for _ in range(5):
        assert tp3.wait_for_reception(timeout=1.0) is not None
    vals = {v.name.split(".")[-1]: v.raw for v in tp3}
    # REAL32 in SI units: no scale (the plant moves within ±0.5 rad)
    assert abs(vals["q"]) < 1.0, vals
    assert vals["temperature"] == 30.0, vals
    assert vals["mode"] == 1 and vals["faults"] == 0, vals
    # and the frame itself: a 32-byte FD frame with bit-rate switch (python-can's Message)
    frames.get_message(0)
    deadline = time.monotonic() + 1.0
    msg = None
    while time.monotonic() < deadline:
        m = frames.get_message(0.1)
        if m is not None and m.arbitration_id == 0x380 + FD_NODE:
            msg = m
            break
    assert msg is not None and msg.is_fd and msg.bitrate_switch and msg.dlc == 32, msg
    assert struct.unpack_from("<f", msg.data, 24)[0] == 30.0
    preop(node)


def test_fd_shared_command_frame_and_sdo_in_fd_frames(fd_rig):
    network, node, frames = fd_rig
    node.nmt.state = "OPERATIONAL"
    time.sleep(0.05)
    # joint 6's slot of the host's shared command frame: bytes 10..12 (assist command, 0.01 N·m)
    cmd = bytearray(12)
    struct.pack_into("<h", cmd, 2 * (FD_NODE - 1), 25)  # 0.25 N·m
    network.bus.send(can.Message(arbitration_id=0x200, data=cmd, is_fd=True, bitrate_switch=True,
                                 is_extended_id=False))
    time.sleep(0.05)
    assert abs(node.sdo[0x2301][10].raw - 0.25) < 1e-6
    # an SDO request in an FD frame gets its reply in an FD frame of 8 bytes
    while frames.get_message(0) is not None:
        pass
    network.bus.send(can.Message(arbitration_id=0x600 + FD_NODE, data=bytes([0x40, 0x18, 0x10, 2, 0, 0, 0, 0]),
                                 is_fd=True, bitrate_switch=True, is_extended_id=False))
    deadline = time.monotonic() + 1.0
    reply = None
    while time.monotonic() < deadline:
        m = frames.get_message(0.1)
        if m is not None and m.arbitration_id == 0x580 + FD_NODE:
            reply = m
            break
    assert reply is not None and reply.is_fd and reply.bitrate_switch and len(reply.data) == 8, reply
    assert reply.data[:4] == bytes([0x43, 0x18, 0x10, 2])
    assert struct.unpack_from("<I", reply.data, 4)[0] == node.sdo[0x1018][2].raw
    preop(node)


@pytest.fixture()
def lss_rig():
    """A second bus with one joint started unconfigured (LSS): serial number 42, no node id."""
    with served("joint-lss-", [], ["--node", "42", "--lss-unconfigured"]) as (network, eds):
        yield network, eds


def test_lss_fast_scan_gives_an_unconfigured_joint_its_node_id(lss_rig):
    """python-canopen's LssMaster: fast scan finds the silent joint, configures and stores its
    node id; back in the waiting state it boots up under that id, the EDS-driven SDO works on
    it, and after an NMT reset node it comes back with the stored id."""
    network, eds = lss_rig
    new_id = 21
    seen = []
    network.subscribe(0x700 + new_id, lambda cob, data, ts: seen.append(bytes(data)))
    time.sleep(0.3)
    assert not seen, "an unconfigured joint sends nothing"
    lss = network.lss
    lss.RESPONSE_TIMEOUT = 0.2
    found, ident = lss.fast_scan()
    assert found, "fast scan found no unconfigured slave"
    cfg = configparser.ConfigParser()
    cfg.read(eds)
    product = int(cfg["DeviceInfo"]["ProductNumber"], 0)
    assert ident == [0, product, int(cfg["DeviceInfo"]["RevisionNumber"], 0), 42]
    # fast scan left it in the configuration state
    assert lss.inquire_node_id() == 0xFF
    lss.configure_node_id(new_id)
    lss.store_configuration()
    node = network.add_node(new_id, str(eds))
    node.sdo.RESPONSE_TIMEOUT = 1.0
    lss.send_switch_state_global(lss.WAITING_STATE)
    wait_for(lambda: b"\x00" in seen, 2, "boot-up under the new node id")
    assert node.sdo["identity"]["serial_number"].raw == 42
    assert node.sdo["identity"]["product_code"].raw == product
    node.sdo["friction_a"].raw = 0.25
    assert node.sdo["friction_a"].raw == 0.25
    # reset node: the stored id, not unconfigured again
    seen.clear()
    node.nmt.send_command(0x81)
    wait_for(lambda: b"\x00" in seen, 2, "boot-up after reset node")
    assert node.sdo["identity"]["serial_number"].raw == 42
    # the configured joint takes no part in another fast scan
    found, _ = lss.fast_scan()
    assert not found
