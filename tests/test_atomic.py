"""Atomic writes: nothing half-written on failure, normal file permissions on success."""
import os
import stat

import pytest

from fabkit.errors import InputError
from fabkit.io.atomic import atomic_path, atomic_write


def test_success_renames_with_umask_permissions(tmp_path):
    target = tmp_path / "out.txt"
    old = os.umask(0o022)
    try:
        with atomic_write(target) as fh:
            fh.write("hello")
        with atomic_path(tmp_path / "b.bin") as tmp:
            tmp.write_bytes(b"x")
    finally:
        os.umask(old)
    assert target.read_text() == "hello"
    assert stat.S_IMODE(target.stat().st_mode) == 0o644
    assert stat.S_IMODE((tmp_path / "b.bin").stat().st_mode) == 0o644
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.bin", "out.txt"]


def test_failure_leaves_nothing_and_keeps_old_file(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_write(target) as fh:
            fh.write("partial")
            raise RuntimeError("boom")
    with pytest.raises(RuntimeError):
        with atomic_path(tmp_path / "b.png") as tmp:
            tmp.write_bytes(b"partial")
            raise RuntimeError("boom")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


def test_missing_directory_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="output directory does not exist"):
        with atomic_write(tmp_path / "no" / "x.txt"):
            pass


def test_staged_writes_commit_together_and_abort_leaves_nothing(tmp_path):
    from fabkit.io.atomic import StagedWrites, is_temp_name

    a, b = tmp_path / "a.txt", tmp_path / "b.png"
    a.write_text("old")
    with StagedWrites() as staged:
        staged.add_file(a)
        staged.add_file(b)
        with atomic_write(a) as fh:
            fh.write("new")
        with atomic_path(b) as tmp:
            assert tmp.suffix == ".png" and is_temp_name(tmp.name)
            tmp.write_bytes(b"png")
        assert a.read_text() == "old" and not b.exists()  # nothing renamed before the commit
        staged.commit()
    assert a.read_text() == "new" and b.read_bytes() == b"png"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.png"]
    with StagedWrites() as staged:
        staged.add_file(a)
        with atomic_write(a) as fh:
            fh.write("never")
    assert a.read_text() == "new"  # left without commit: aborted
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.png"]


def test_a_staged_folder_is_merged_at_commit(tmp_path):
    from fabkit.io.atomic import StagedWrites, staging_path

    out = tmp_path / "run"
    with StagedWrites() as staged:
        staged.add_folder(out)
        with atomic_write(out / "x.txt") as fh:  # a file inside the folder goes to its staging folder
            fh.write("x")
        (staging_path(out) / "sub").mkdir()
        (staging_path(out) / "sub" / "y.txt").write_text("y")
        assert not out.exists()
        staged.commit()
    assert (out / "x.txt").read_text() == "x" and (out / "sub" / "y.txt").read_text() == "y"
    assert [p.name for p in tmp_path.iterdir()] == ["run"]


def test_a_file_written_into_a_staged_folder_is_read_from_the_stage_until_the_commit(tmp_path):
    from fabkit.io.atomic import StagedWrites, written_path

    out = tmp_path / "run"
    with StagedWrites() as staged:
        staged.add_folder(out)
        with atomic_path(out / "sheets" / "s.png") as tmp:
            tmp.write_bytes(b"png")
        here = written_path(out / "sheets" / "s.png")
        assert here != out / "sheets" / "s.png" and here.read_bytes() == b"png"
        assert written_path(out / "none.png") == out / "none.png"  # not written: the path itself
        staged.commit()
    assert written_path(out / "sheets" / "s.png") == out / "sheets" / "s.png"


def test_write_errors_name_the_target(tmp_path):
    import resource

    from fabkit.errors import OutputError

    saved = resource.getrlimit(resource.RLIMIT_FSIZE)
    try:
        resource.setrlimit(resource.RLIMIT_FSIZE, (100, saved[1]))
        with pytest.raises(OutputError, match="out.txt: cannot write: the file is larger than the file-size limit"):
            with atomic_write(tmp_path / "out.txt") as fh:
                fh.write("x" * 10_000)
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, saved)
    assert list(tmp_path.iterdir()) == []


def test_temporary_names_fit_the_name_limit_and_stale_ones_are_cleaned(tmp_path):
    import subprocess
    import sys

    from fabkit.io.atomic import clean_stale, is_temp_name, temp_sibling

    long = tmp_path / ("n" * 250 + ".obj")
    tmp = temp_sibling(long)
    assert len(tmp.name.encode()) <= 255 and is_temp_name(tmp.name) and tmp.suffix == ".obj"
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True,
                          timeout=30).stdout.strip()
    (tmp_path / f".x.fabkit-{dead}-00ff.tmp").write_text("stale")
    (tmp_path / f".d.fabkit-{dead}-00ff.tmp").mkdir()
    (tmp_path / f".y.fabkit-{os.getpid()}-00ff.tmp").write_text("mine")
    (tmp_path / ".z.tmp").write_text("not ours")
    clean_stale(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == [".y.fabkit-%d-00ff.tmp" % os.getpid(), ".z.tmp"]
