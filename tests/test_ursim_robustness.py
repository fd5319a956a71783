"""No client can wedge the stand-in: faults are validated before anything is scheduled, every text
port has bounded lines and scripts (error reply, connection closed, no quadratic rescans), `play`
of a rejected program is refused with the client kept, output recipes past id 255 are refused,
clients are capped per port, `load` stays inside --programs, and dashboard `shutdown` stops the
process with every connection closed. The stand-in runs in its own process."""
import socket
import struct
import time

import pytest

from _ursim import StandIn, external_host

pytestmark = [pytest.mark.network, pytest.mark.skipif(external_host() is not None,
                                                      reason="robustness checks need the stand-in")]


@pytest.fixture(scope="module")
def programs(tmp_path_factory):
    d = tmp_path_factory.mktemp("programs")
    (d / "broken.script").write_text("def broken():\n  explode()\nend\n")
    (d / "hold.script").write_text("def hold():\n  sleep(0.2)\nend\n")
    return d


@pytest.fixture(scope="module")
def standin(tmp_path_factory, programs):
    s = StandIn("--programs", str(programs), log=tmp_path_factory.mktemp("ursim") / "ursim.log")
    yield s
    s.stop()


class Lines:
    """A line client of the dashboard (29999) or admin (30020) port."""

    def __init__(self, host, port, banner=False):
        self.sock = socket.create_connection((host, port), timeout=5)
        self.buf = b""
        if banner:
            assert self.line().startswith("Connected: Universal Robots Dashboard Server")

    def line(self) -> str:
        while b"\n" not in self.buf:
            data = self.sock.recv(65536)
            if not data:
                raise ConnectionError("closed")
            self.buf += data
        out, self.buf = self.buf.split(b"\n", 1)
        return out.decode()

    def ask(self, text: str) -> str:
        self.sock.sendall((text + "\n").encode())
        return self.line()

    def closed_by_server(self, timeout=5.0) -> bool:
        self.sock.settimeout(timeout)
        try:
            while True:
                data = self.sock.recv(65536)
                if not data:
                    return True
        except (ConnectionResetError, BrokenPipeError):
            return True
        except socket.timeout:
            return False

    def close(self):
        self.sock.close()


def _idle_log(standin) -> list[str]:
    return standin.state()["log_tail"]


@pytest.mark.parametrize("line", ["after 0 bogus", "at_progress 3 gremlins", "after nan protective_stop",
                                  "after -1 estop", "after 1e9 estop", "at_progress -4 estop", "at_progress x estop",
                                  "after 0 stall -1", "after 0 stall abc", "after 0 slow 0.1,0",
                                  "after 0 slow x", "after 0 drop_rtde now", "at_progress 1", "stall inf",
                                  "slow 1,2,3", "bogus", "program_stop please"])
def test_bad_faults_are_refused_and_nothing_is_scheduled(standin, line):
    import json

    a = Lines(standin.host, 30020)
    try:
        reply = json.loads(a.ask(line))
    finally:
        a.close()
    assert reply["ok"] is False and reply["error"]
    st = standin.state()
    assert st["pending_faults"] == 0 and st["safety_mode"] == "NORMAL" and st["robot_mode"] == "RUNNING"


def test_no_error_storm_after_a_refused_fault(standin):
    standin.admin("after 0 bogus")
    time.sleep(0.3)
    assert not any("error in the control tick" in ln for ln in _idle_log(standin))


@pytest.mark.parametrize("port,banner", [(29999, True), (30020, False)])
def test_a_huge_line_gets_an_error_and_is_closed_fast(standin, port, banner):
    c = Lines(standin.host, port, banner=banner)
    t0 = time.monotonic()
    try:
        c.sock.sendall(b"x" * (8 << 20))  # 8 MiB without a newline
    except (BrokenPipeError, ConnectionResetError):
        pass
    try:
        reply = c.line()
    except (ConnectionError, ConnectionResetError):
        reply = None
    assert reply is None or "could not understand" in reply or '"ok": false' in reply
    assert c.closed_by_server()
    assert time.monotonic() - t0 < 5.0
    c.close()
    d = Lines(standin.host, 29999, banner=True)  # the port still serves others
    assert d.ask("robotmode") == "Robotmode: RUNNING"
    d.close()


def test_an_unterminated_script_is_refused_at_the_limit(standin):
    from sim.ursim.script_ports import MAX_SCRIPT

    s = socket.create_connection((standin.host, 30002), timeout=5)
    t0 = time.monotonic()
    body = b"def endless():\n" + b"  textmsg(\"x\")\n" * 1000
    sent = 0
    try:
        while sent < MAX_SCRIPT + (1 << 20):
            s.sendall(body)
            body = b"  textmsg(\"x\")\n" * 1000
            sent += len(body)
    except (BrokenPipeError, ConnectionResetError):
        pass
    s.settimeout(5)
    closed = False
    try:
        while True:
            if not s.recv(1 << 16):
                closed = True
                break
    except (ConnectionResetError, BrokenPipeError):
        closed = True
    s.close()
    assert closed and time.monotonic() - t0 < 10.0
    assert "program refused, connection closed" in standin.state()["last_error"]


def test_play_of_a_rejected_program_is_refused_and_the_client_kept(standin):
    d = Lines(standin.host, 29999, banner=True)
    try:
        assert d.ask("load broken.script") == "Loading program: broken.script"
        assert d.ask("play") == "Failed to execute: play"
        assert d.ask("robotmode") == "Robotmode: RUNNING"  # same connection, still answered
    finally:
        d.close()


@pytest.mark.parametrize("name", ["/etc/hostname", "../x", "../../etc/hostname", "sub/../../x.script", ""])
def test_load_stays_inside_the_programs_directory(standin, programs, name):
    (programs.parent / "x.script").write_text("def x():\n  sleep(0.1)\nend\n")
    d = Lines(standin.host, 29999, banner=True)
    try:
        reply = d.ask(f"load {name}")
    finally:
        d.close()
    assert reply.startswith("File not found") or reply.startswith("could not understand")


def test_300_output_recipes_on_one_connection(standin):
    s = socket.create_connection((standin.host, 30004), timeout=5)
    buf = b""

    def recv():
        nonlocal buf
        while True:
            if len(buf) >= 3:
                size, kind = struct.unpack_from(">HB", buf)
                if len(buf) >= size:
                    pkg, buf = buf[:size], buf[size:]
                    return chr(kind), pkg[3:]
            data = s.recv(65536)
            assert data, "the stand-in closed the connection"
            buf += data

    def send(kind, payload=b""):
        s.sendall(struct.pack(">HB", 3 + len(payload), kind[0]) + payload)

    send(b"V", struct.pack(">H", 2))
    assert recv() == ("V", b"\x01")
    ids = []
    for _ in range(300):
        send(b"O", struct.pack(">d", 500.0) + b"timestamp,actual_q,")
        kind, payload = recv()
        assert kind == "O"
        ids.append(payload[0])
    assert ids[:255] == list(range(1, 256)) and set(ids[255:]) == {0}
    send(b"S")  # the last accepted recipe (255) still streams
    assert recv() == ("S", b"\x01")
    kind, payload = recv()
    assert kind == "U" and payload[0] == 255 and len(payload) == 1 + 8 + 48
    s.close()


def _closed_within(sock, timeout) -> bool:
    sock.settimeout(timeout)
    try:
        return sock.recv(1) == b""
    except socket.timeout:
        return False
    except ConnectionResetError:
        return True


def test_clients_are_capped_per_port(standin):
    from sim.ursim.clients import MAX_CLIENTS_PER_PORT

    socks = []
    try:
        for _ in range(MAX_CLIENTS_PER_PORT + 5):
            socks.append(socket.create_connection((standin.host, 30020), timeout=5))
            time.sleep(0.01)
        closed = [_closed_within(s, 0.3) for s in socks]
        assert closed == [False] * MAX_CLIENTS_PER_PORT + [True] * 5
        d = Lines(standin.host, 29999, banner=True)  # other ports are not affected
        assert d.ask("robotmode") == "Robotmode: RUNNING"
        d.close()
    finally:
        for s in socks:
            s.close()
    time.sleep(0.3)
    assert standin.admin("state")["ok"]  # served again once the others left


def test_dashboard_shutdown_stops_the_process_and_closes_every_client(tmp_path):
    s = StandIn(log=tmp_path / "ursim.log")
    try:
        rt = socket.create_connection((s.host, 30003), timeout=5)
        rt.recv(1220)
        d = Lines(s.host, 29999, banner=True)
        assert d.ask("shutdown") == "Shutting down"
        assert s.proc.wait(timeout=10) == 0
        rt.settimeout(5)
        closed = False
        try:
            while rt.recv(1 << 16):
                pass
            closed = True
        except (ConnectionResetError, OSError):
            closed = True
        assert closed
        rt.close()
        d.close()
    finally:
        s.stop()
