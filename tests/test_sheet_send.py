"""The payload of a sheet program through the real ur_rtde to the controller stand-in: `fabkit send`
of a program planned with a material declares the tool, then tool + panel after the grip, then the
tool again after the release (`setPayload`), each as PATH.json records it; without a material
nothing about the payload is sent."""
import json

import pytest

from _ursim import standin_fixture
from fabkit.cli import main as fabkit_main
from sheet_panels import CELL, GROOVED, crease_600_fold, plan

pytestmark = pytest.mark.network

standin = standin_fixture("--cell", CELL)
FAST = ["--fold-speed", "0.25"]  # the cell's TCP limit: keeps the sends short


@pytest.fixture(scope="module")
def fold(tmp_path_factory):
    return crease_600_fold(tmp_path_factory.mktemp("crease600"))


def test_the_reflect_presets_urscript_sets_the_payload_on_the_stand_in(standin, tmp_path):
    """The acceptance case: the reflect preset with 1 mm 5052-H32; its URScript, sent as text to the
    secondary port, declares the tool, tool + panel and the tool again, as PATH.json records them.
    (First in the module: the stand-in starts at the cell's home, where the program starts, and no
    sender has armed its RTDE watchdog yet, which a URScript program does not kick.)"""
    import socket
    import time

    from robot.urscript import PROGRESS_REGISTER

    d = tmp_path
    for argv in (["generate", "reflect", "-o", str(d / "panel.obj"), "-q"],
                 ["unfold", str(d / "panel.obj"), "-o", str(d / "flat.obj"), "-q"],
                 ["refold", str(d / "flat.obj"), str(d / "panel.obj"), "-o", str(d / "seq.fold"), "-q",
                  "--frames", "5"],
                 ["toolpath", str(d / "seq.fold"), "--cell", CELL, "-o", str(d / "path.json"), "--script",
                  str(d / "fold.script"), "-q", "--material", "5052-H32", "--thickness", "1mm", *FAST]):
        assert fabkit_main(argv) == 0, argv
    doc = json.loads((d / "path.json").read_text())
    pay, n = doc["payload"], len(doc["waypoints"])
    assert standin.admin("record clear")["ok"]
    with socket.create_connection((standin.host, 30002), timeout=5.0) as s:
        s.sendall((d / "fold.script").read_bytes())
    deadline = time.monotonic() + 120.0
    while standin.state()["out_int"][PROGRESS_REGISTER] != n:
        assert time.monotonic() < deadline, standin.log_text()[-1500:]
        assert not standin.state()["last_error"]
        time.sleep(0.1)
    got = [(r["mass"], r["cog"]) for r in standin.admin("record")["commands"]
           if r["command"] == "set_payload" and r["source"] == "urscript"]
    assert got == [(pay["tool_mass_kg"], pay["tool_cog_m"]), (pay["held_mass_kg"], pay["held_cog_m"]),
                   (pay["tool_mass_kg"], pay["tool_cog_m"])]


def _send(capsys, standin, path):
    check = path.with_suffix(".check.json")
    assert fabkit_main(["check", str(path), "--cell", CELL, "-o", str(check), "-q"]) == 0
    log = path.with_suffix(".log")
    assert standin.admin("record clear")["ok"]
    capsys.readouterr()
    rc = fabkit_main(["send", str(path), "--check", str(check), "--cell", CELL, "--host", standin.host,
                      "--log", str(log)])
    out, err = capsys.readouterr()
    assert rc == 0, err
    events = [json.loads(line) for line in log.read_text().splitlines()]
    return events, standin.admin("record")["commands"]


def test_send_declares_the_payload_before_motion_and_at_grip_and_release(standin, fold, capsys):
    path = plan(fold, fold.with_name("grooved.json"), *GROOVED, *FAST)
    pay = json.loads(path.read_text())["payload"]
    events, record = _send(capsys, standin, path)
    payloads = [r for r in record if r["command"] == "set_payload"]
    assert [r["source"] for r in payloads] == ["register"] * 3  # ur_rtde's setPayload (register command 17)
    want = [(pay["tool_mass_kg"], pay["tool_cog_m"]), (pay["held_mass_kg"], pay["held_cog_m"]),
            (pay["tool_mass_kg"], pay["tool_cog_m"])]
    for r, (mass, cog) in zip(payloads, want):
        assert r["mass"] == mass and r["cog"] == cog  # doubles bit for bit
    assert pay["held_mass_kg"] == pytest.approx(0.5 + pay["panel_mass_kg"]) and pay["panel_mass_kg"] > 0.9
    # the first payload before the first motion; the held one between the grip and the next motion
    kinds = [r["command"] for r in record]
    first_move = next(i for i, k in enumerate(kinds) if k.lower().startswith("move"))
    assert kinds.index("set_payload") < first_move
    steps = [e for e in events if e.get("step") in ("gripper", "payload")]
    assert [(e["step"], e.get("on", e.get("held"))) for e in steps] == [
        ("gripper", False), ("payload", False), ("gripper", True), ("payload", True), ("gripper", False),
        ("payload", False)]
    state = standin.state()
    assert state["payload"] == pay["tool_mass_kg"] and state["payload_cog"] == pay["tool_cog_m"]


def test_send_without_a_material_sends_no_payload(standin, fold, capsys):
    path = plan(fold, fold.with_name("rigid.json"), *FAST)
    assert "payload" not in json.loads(path.read_text())
    events, record = _send(capsys, standin, path)
    assert not [r for r in record if r["command"] == "set_payload"]
    assert not [e for e in events if e.get("step") == "payload"]
    calls = [e for e in events if e.get("call") == "connect_receive"]
    assert calls and calls[0]["args"][1] is False  # the receive recipe of today (no payload variables)


def test_a_payload_the_controller_dropped_stops_the_send(fold):
    """The watch every poll makes: a controller reporting another payload than the one declared
    (e.g. reset when a new program started) is a fault; before a payload is declared nothing is compared."""
    from robot.preflight import ControllerFault
    from robot.send_tool import ToolControl
    from robot.toolpath import Toolpath

    tp = Toolpath.load(plan(fold, fold.with_name("watch.json"), *GROOVED))
    tool = ToolControl(tp, call=None, poll=None, event=lambda **kw: None, fault=ControllerFault)
    mass, cog = tool.payload_for(True)
    assert mass == tp.extra["payload"]["held_mass_kg"] and list(cog) == tp.extra["payload"]["held_cog_m"]
    tool.verify_payload({"payload": 0.0, "payload_cog": [0.0, 0.0, 0.0]})  # nothing declared yet
    tool.declared = (mass, cog)
    tool.verify_payload({"payload": mass, "payload_cog": list(cog)})
    with pytest.raises(ControllerFault, match="is not the declared"):
        tool.verify_payload({"payload": 0.0, "payload_cog": list(cog)})
    with pytest.raises(ControllerFault, match="is not the declared"):
        tool.verify_payload({"payload": mass, "payload_cog": [cog[0], cog[1], cog[2] + 1e-3]})
