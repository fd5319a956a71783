"""The stand-in's protocols on loopback: RTDE v2 bytes on the wire (framing, recipes, types,
NOT_FOUND, IN_USE, input recipe numbering, streaming, pause), the real ur_rtde receive / IO /
dashboard clients, and the script ports with fabkit's URScript. The stand-in runs in its own
process on this module's loopback addresses and is always stopped."""
import socket
import struct
import time

import numpy as np
import pytest

from _ursim import StandIn, external_host
from robot import kinematics as K
from sim.ursim.rtde_vars import OUTPUTS, TYPE_FORMATS, receive_default_variables

pytestmark = [pytest.mark.network, pytest.mark.skipif(external_host() is not None,
                                                      reason="wire-level and fault checks need the stand-in")]


@pytest.fixture(scope="module")
def programs(tmp_path_factory):
    return tmp_path_factory.mktemp("programs")


@pytest.fixture(scope="module")
def standin(tmp_path_factory, programs):
    s = StandIn("--unlock-delay", "5", "--programs", str(programs),
                log=tmp_path_factory.mktemp("ursim") / "ursim.log")
    yield s
    s.stop()


class RawRTDE:
    """A minimal RTDE client speaking bytes (to test the server, not ur_rtde)."""

    def __init__(self, host):
        self.sock = socket.create_connection((host, 30004), timeout=5)
        self.buf = b""

    def send(self, kind: bytes, payload: bytes = b"") -> None:
        self.sock.sendall(struct.pack(">HB", 3 + len(payload), kind[0]) + payload)

    def recv(self):
        while True:
            if len(self.buf) >= 3:
                size, kind = struct.unpack_from(">HB", self.buf)
                if len(self.buf) >= size:
                    pkg, self.buf = self.buf[:size], self.buf[size:]
                    return chr(kind), pkg[3:]
            data = self.sock.recv(65536)
            assert data, "server closed the connection"
            self.buf += data

    def setup_outputs(self, names, freq=500.0):
        self.send(b"O", struct.pack(">d", freq) + (",".join(names) + ",").encode())
        kind, payload = self.recv()
        assert kind == "O"
        return payload[0], payload[1:].decode().split(",")

    def setup_inputs(self, names):
        self.send(b"I", (",".join(names) + ",").encode())
        kind, payload = self.recv()
        assert kind == "I"
        return payload[0], payload[1:].decode().split(",")

    def close(self):
        self.sock.close()


def _fmt(types):
    return struct.Struct(">B" + "".join(TYPE_FORMATS[t] for t in types))


def test_version_and_framing_of_several_packages_in_one_write(standin):
    c = RawRTDE(standin.host)
    # V and v in one write, the second split across two writes: the server must frame the stream
    v_pkg = struct.pack(">HBH", 5, ord("V"), 2)
    vv = struct.pack(">HB", 3, ord("v"))
    c.sock.sendall(v_pkg + vv[:1])
    time.sleep(0.05)
    c.sock.sendall(vv[1:])
    assert c.recv() == ("V", b"\x01")
    kind, payload = c.recv()
    assert kind == "v" and struct.unpack(">IIII", payload) == (5, 15, 0, 0)
    c.close()


def test_output_recipe_types_sizes_and_stream(standin):
    c = RawRTDE(standin.host)
    c.send(b"V", struct.pack(">H", 2))
    c.recv()
    names = receive_default_variables((5, 15, 0, 0))
    assert len(names) == 58
    rid, types = c.setup_outputs(names)
    assert rid >= 1 and types == [OUTPUTS[n] for n in names]
    st = _fmt(types)
    assert st.size + 3 == 1180 + 3 - 3  # ur_rtde's 1180-byte package at 5.15: header + id + 58 variables
    c.send(b"S")
    assert c.recv() == ("S", b"\x01")
    stamps, qs = [], []
    for _ in range(100):
        kind, payload = c.recv()
        assert kind == "U" and len(payload) == st.size
        vals = st.unpack(payload)
        stamps.append(vals[1])
        qs.append(vals[1 + 1 + 6 * 5: 1 + 1 + 6 * 6])  # actual_q is the 7th variable
    steps = np.diff(stamps)
    assert np.all(steps > 0)
    assert np.allclose(steps / 0.002, np.round(steps / 0.002), atol=1e-6)  # whole controller periods
    assert np.allclose(qs[-1], standin.state()["q"], atol=1e-12)
    c.send(b"P")
    # data packages already in flight may precede the pause reply
    for _ in range(100):
        kind, payload = c.recv()
        if kind == "P":
            break
    assert payload == b"\x01"
    c.close()


def test_unknown_output_gets_not_found(standin):
    c = RawRTDE(standin.host)
    c.send(b"V", struct.pack(">H", 2))
    c.recv()
    rid, types = c.setup_outputs(["timestamp", "no_such_var", "actual_q"])
    assert rid == 0 and types == ["DOUBLE", "NOT_FOUND", "VECTOR6D"]
    c.send(b"S")
    assert c.recv() == ("S", b"\x00")  # nothing to stream
    c.close()


def test_input_recipes_numbered_per_connection_and_single_writer(standin):
    a, b = RawRTDE(standin.host), RawRTDE(standin.host)
    for c in (a, b):
        c.send(b"V", struct.pack(">H", 2))
        c.recv()
    assert a.setup_inputs(["input_int_register_0"]) == (1, ["INT32"])
    assert a.setup_inputs(["input_int_register_0", "input_double_register_5"]) == (2, ["INT32", "DOUBLE"])
    assert a.setup_inputs(["input_int_register_0"]) == (3, ["INT32"])  # the same recipe again is fine
    assert b.setup_inputs(["input_int_register_0"]) == (0, ["IN_USE"])
    assert b.setup_inputs(["input_int_register_30", "bogus_input"]) == (0, ["INT32", "NOT_FOUND"])
    assert b.setup_inputs(["input_int_register_30"]) == (1, ["INT32"])  # b numbers its own recipes
    # a data package on recipe 2 sets both inputs; a stream of inputs reads them back
    a.send(b"U", struct.pack(">Bid", 2, 42, -1.25))
    rid, _ = b.setup_outputs(["input_int_register_0", "input_double_register_5"], 125.0)
    b.send(b"S")
    assert b.recv() == ("S", b"\x01")
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:
        kind, payload = b.recv()
        if kind == "U" and struct.unpack(">Bid", payload)[1:] == (42, -1.25):
            break
    else:
        pytest.fail("inputs never read back")
    # ownership ends with the connection
    a.close()
    time.sleep(0.2)
    c = RawRTDE(standin.host)
    c.send(b"V", struct.pack(">H", 2))
    c.recv()
    assert c.setup_inputs(["input_int_register_0"]) == (1, ["INT32"])
    for x in (b, c):
        x.close()


def test_real_receive_interface_default_variables(standin):
    import rtde_receive

    r = rtde_receive.RTDEReceiveInterface(standin.host)
    try:
        state = standin.state()
        q = np.array(r.getActualQ())
        assert np.allclose(q, state["q"], atol=1e-12)
        T = K.fk_tcp("ur5e", q, np.eye(4))
        assert np.allclose(r.getActualTCPPose()[:3], T[:3, 3], atol=1e-12)
        assert r.getRobotMode() == 7 and r.getSafetyMode() == 1 and r.getSafetyStatusBits() == 1
        assert list(r.getJointMode()) == [253] * 6
        assert r.getActualToolAccelerometer() == [0.0, 0.0, 9.81]  # a 3-vector parsed in place
        assert r.getPayloadInertia() == [0.0] * 6 and r.getFtRawWrench() == [0.0] * 6
        t0 = r.getTimestamp()
        deadline = time.monotonic() + 5
        while r.getTimestamp() <= t0 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert r.getTimestamp() > t0
    finally:
        r.disconnect()


def test_real_io_interface_sets_outputs(standin):
    import rtde_io
    import rtde_receive

    io = rtde_io.RTDEIOInterface(standin.host)
    r = rtde_receive.RTDEReceiveInterface(standin.host)
    try:
        assert io.setStandardDigitalOut(3, True)
        assert io.setToolDigitalOut(1, True)
        deadline = time.monotonic() + 5
        want = (1 << 3) | (1 << 17)
        while (r.getActualDigitalOutputBits() & want) != want and time.monotonic() < deadline:
            time.sleep(0.01)
        assert r.getActualDigitalOutputBits() & want == want
        assert io.setStandardDigitalOut(3, False)
        deadline = time.monotonic() + 5
        while r.getActualDigitalOutputBits() & (1 << 3) and time.monotonic() < deadline:
            time.sleep(0.01)
        assert not r.getActualDigitalOutputBits() & (1 << 3) and r.getActualDigitalOutputBits() & (1 << 17)
    finally:
        io.disconnect()
        r.disconnect()


def test_dashboard_replies_and_protective_stop_unlock_rule(standin, tmp_path):
    import dashboard_client

    d = dashboard_client.DashboardClient(standin.host)
    d.connect()
    try:
        assert d.polyscopeVersion() == "5.15.0.0"  # parsed from "URSoftware 5.15.0.0 (...)"
        assert d.getSerialNumber().isdigit()
        assert d.isInRemoteControl()
        assert d.robotmode() == "Robotmode: RUNNING"
        assert d.safetystatus() == "Safetystatus: NORMAL"
        assert not d.running()
        assert d.programState().startswith("STOPPED")
        d.send("no such command\n")
        assert d.receive().strip() == "could not understand: 'no such command'"
        with pytest.raises(RuntimeError, match="File not found"):
            d.loadURP("missing.urp")
        d.powerOff()
        assert d.robotmode() == "Robotmode: POWER_OFF"
        d.powerOn()
        assert d.robotmode() == "Robotmode: IDLE"
        d.brakeRelease()
        assert d.robotmode() == "Robotmode: RUNNING"
        # protective stop: unlock is refused for 5 s, then accepted
        t_stop = time.monotonic()
        assert standin.admin("protective_stop")["ok"]
        assert d.safetystatus() == "Safetystatus: PROTECTIVE_STOP"
        with pytest.raises(RuntimeError, match="Cannot unlock protective stop until 5s after occurrence"):
            d.unlockProtectiveStop()
        time.sleep(max(0.0, 5.1 - (time.monotonic() - t_stop)))
        d.unlockProtectiveStop()  # raises unless the reply is exactly "Protective stop releasing"
        d.closeSafetyPopup()
        assert d.safetystatus() == "Safetystatus: NORMAL"
        d.stop()  # raises unless the reply is exactly "Stopped"
    finally:
        d.disconnect()


def _wait(cond, timeout=10.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.02)
    return False


def test_script_port_runs_fabkit_urscript_and_rejects_the_rest(standin):
    q0 = np.array(standin.state()["q"])
    target = q0 + np.array([0.2, -0.1, 0.1, 0.0, 0.1, -0.2])
    qs = ", ".join(repr(float(x)) for x in target)
    program = f"""def fabkit_test():
  # written like robot/urscript output
  set_tcp(p[0.0, 0.0, 0.13, 0.0, 0.0, 0.0])
  movej([{qs}], a=1.4, v=1.05, r=0)
  set_standard_digital_out(5, True)
  write_output_integer_register(21, 1234)
  textmsg("done")
end
"""
    with socket.create_connection((standin.host, 30002), timeout=5) as s:
        s.sendall(program.encode())
    assert _wait(lambda: standin.state()["digital_out"] & (1 << 5))
    st = standin.state()
    assert np.allclose(st["q"], target, atol=1e-12)
    assert st["tcp_offset"] == pytest.approx([0, 0, 0.13, 0, 0, 0])
    assert st["runtime_state"] == 1  # the program ended
    # a program the controller would not compile: refused, nothing runs
    with socket.create_connection((standin.host, 30001), timeout=5) as s:
        s.sendall(b"def bad():\n  movej([0, 0, 0, 0, 0, 0], a=1.4, v=1.05)\n  while True:\n  end\nend\n")
    assert _wait(lambda: (standin.state()["last_error"] or "").startswith("compile error"))
    assert np.allclose(standin.state()["q"], target, atol=1e-12)


@pytest.fixture(scope="module")
def standin_cb3(tmp_path_factory):
    s = StandIn("--version", "3.15.7", log=tmp_path_factory.mktemp("ursim_cb3") / "ursim.log")
    yield s
    s.stop()


def test_cb3_version_streams_at_125_hz(standin_cb3):
    import rtde_receive

    c = RawRTDE(standin_cb3.host)
    c.send(b"V", struct.pack(">H", 2))
    c.recv()
    c.send(b"v")
    assert struct.unpack(">IIII", c.recv()[1]) == (3, 15, 7, 0)
    assert c.setup_outputs(["timestamp"], 500.0)[0] == 0  # faster than the CB3 loop: refused
    rid, _ = c.setup_outputs(["timestamp"], 125.0)
    assert rid >= 1
    c.send(b"S")
    c.recv()
    stamps = [struct.unpack(">Bd", c.recv()[1])[1] for _ in range(20)]
    steps = np.diff(stamps)
    assert np.allclose(steps / 0.008, np.round(steps / 0.008), atol=1e-6) and np.all(steps > 0)
    c.close()
    import rtde_control

    r = rtde_receive.RTDEReceiveInterface(standin_cb3.host)  # frequency -1 -> 125 Hz for CB3
    ctrl = rtde_control.RTDEControlInterface(standin_cb3.host, -1.0,
                                             rtde_control.RTDEControlInterface.FLAG_UPLOAD_SCRIPT, 50002, -1)
    try:
        assert r.getRobotMode() == 7
        target = np.array(r.getActualQ()) + 0.05
        assert ctrl.moveJ(target.tolist())  # the CB3 control script (3.x recipes) at 125 Hz
        assert np.abs(np.array(r.getActualQ()) - target).max() < 1e-4
    finally:
        ctrl.stopScript()
        ctrl.disconnect()
        r.disconnect()


def test_dashboard_load_play_pause_stop(standin, programs):
    import dashboard_client

    q0 = np.array(standin.state()["q"])
    (programs / "wave.script").write_text(
        "def wave():\n"
        f"  movej([{', '.join(repr(float(x)) for x in q0 + 0.3)}], a=1.0, v=0.3, r=0)\n"
        f"  movej([{', '.join(repr(float(x)) for x in q0)}], a=1.0, v=0.3, r=0)\n"
        "end\n")
    d = dashboard_client.DashboardClient(standin.host)
    d.connect()
    try:
        d.loadURP("wave.urp")  # raises unless the reply contains "Loading program:"
        assert d.getLoadedProgram().endswith("wave.script")
        d.play()  # raises unless the reply is exactly "Starting program"
        assert _wait(lambda: d.running())
        assert d.programState() == "PLAYING wave"
        d.pause()
        assert d.programState() == "PAUSED wave"
        q_paused = np.array(standin.state()["q"])
        time.sleep(0.1)
        assert np.array_equal(np.array(standin.state()["q"]), q_paused)  # paused: the arm holds
        d.play()
        assert d.programState() == "PLAYING wave"
        d.stop()
        assert not d.running() and d.programState().startswith("STOPPED")
    finally:
        d.disconnect()
