"""`fabkit ursim` / `python -m sim.ursim` refuse option values the stand-in cannot honour before it
binds anything: exit 2 with one line naming the option."""
import pytest

from fabkit.cli import main as fabkit_main
from sim.ursim.__main__ import main as ursim_main

BAD = [
    (["--q0", "99,0,0,0,0,0"], "--q0"),
    (["--q0", "0,0,0"], "--q0"),
    (["--q0", "nan,0,0,0,0,0"], "--q0"),
    (["--unlock-delay", "-1"], "--unlock-delay"),
    (["--unlock-delay", "inf"], "--unlock-delay"),
    (["--fault", "stall:-1"], "--fault"),
    (["--fault", "gremlins"], "--fault"),
    (["--fault", "estop@progress=-3"], "--fault"),
    (["--fault", "slow:0.1,0"], "--fault"),
    (["--rt-priority", "500"], "--rt-priority"),
    (["--rt-priority", "-1"], "--rt-priority"),
    (["--admin-port", "99999"], "--admin-port"),
    (["--admin-port", "0"], "--admin-port"),
    (["--admin-port", "29999"], "--admin-port"),
    (["--host", "8.8.8.8"], "--host"),
    (["--host", "not a host"], "--host"),
    (["--version", "7.1"], "--version"),
    (["--admin-port", "x"], "--admin-port"),
]


@pytest.mark.parametrize("args,option", BAD)
@pytest.mark.parametrize("entry", ["fabkit", "module"])
def test_bad_options_exit_2_with_one_line(args, option, entry, capsys, tmp_path):
    argv = ["--host", "127.0.0.251", *args, "--log", str(tmp_path / "u.log")]
    rc = _exit_code(fabkit_main, ["ursim", *argv]) if entry == "fabkit" else _exit_code(ursim_main, argv)
    out, err = capsys.readouterr()
    assert rc == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and option in err, err
    assert not (tmp_path / "u.log").exists()  # refused before anything was written


def _exit_code(fn, argv) -> int:
    try:
        return fn(argv)
    except SystemExit as exc:  # argparse usage errors
        return exc.code
