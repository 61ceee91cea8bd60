"""Nothing a user owns is overwritten or corrupted: every command refuses an output that is one
of its inputs (the log, a calibration, a column map; also through a symbolic link) or another
of its outputs, before any work (exit 2, the file unchanged); and an output is written whole or
not at all (a failure half way leaves the previous file as it was, no truncated one)."""
import os
import subprocess
import sys

import numpy as np
import pytest

from imufuse import io, sim
from imufuse.shared.atomic import replacing
from cli_here import imf_here


def _cli(*args, cwd=None):
    """The command line through main() in this process (its messages, exit codes and files)."""
    return imf_here(*args, cwd=cwd)


@pytest.fixture
def log(tmp_path):
    d = sim.imu("slow", rate=100.0, duration=5.0, seed=2)
    p = tmp_path / "log.csv"
    io.write_log(str(p), d.t, d.gyr, d.acc)
    return p


def _vario_log(tmp_path):
    d = sim.imu("slow", rate=100.0, duration=5.0, seed=2)
    p = tmp_path / "vlog.csv"
    io.write_log(str(p), d.t, d.gyr, d.acc, extra={"pressure": np.full(len(d.t), 101325.0)})
    return p


def _unchanged(path, before):
    assert path.read_bytes() == before


def test_run_refuses_its_calibration_and_column_map(tmp_path, log):
    cal = tmp_path / "cal.json"
    cal.write_text('{"gyroscope": {"offset": [0, 0, 0]}}\n')
    before = cal.read_bytes()
    p = _cli("run", log, "-f", "MadgwickIMU", "--calibration", cal, "-o", cal)
    assert p.returncode == 2 and "is the input" in p.stderr, p.stderr
    _unchanged(cal, before)
    cmap = tmp_path / "map.txt"
    cmap.write_text("gyr_x = gyr_x\n")
    before = cmap.read_bytes()
    p = _cli("run", log, "-f", "MadgwickIMU", "--column-map", cmap, "-o", cmap)
    assert p.returncode == 2 and "is the input" in p.stderr, p.stderr
    _unchanged(cmap, before)


def test_two_outputs_on_one_file(tmp_path, log):
    out = tmp_path / "x.png"
    p = _cli("run", log, "-f", "MadgwickIMU", "-o", out, "--plot", out)
    assert p.returncode == 2 and "is also the -o output" in p.stderr, p.stderr
    assert not out.exists()


def test_vario_refuses_its_log_also_through_a_link(tmp_path):
    vlog = _vario_log(tmp_path)
    before = vlog.read_bytes()
    link = tmp_path / "link.csv"
    link.symlink_to(vlog)
    for target in (vlog, link):
        p = _cli("vario", vlog, "-o", target, "--no-plot")
        assert p.returncode == 2 and "is the input" in p.stderr, p.stderr
        _unchanged(vlog, before)


def test_calibrate_refuses_its_log(tmp_path, log):
    before = log.read_bytes()
    p = _cli("calibrate", "gyro", log, "-o", log)
    assert p.returncode == 2 and "is the input" in p.stderr, p.stderr
    _unchanged(log, before)


def test_validate_plot_refuses_the_firmware_source(tmp_path):
    fw = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "examples",
                      "firmware-tests")
    src = tmp_path / "cf.c"
    src.write_text(open(os.path.join(fw, "cf.c")).read())
    before = src.read_bytes()
    p = _cli("validate", src, "--header", "cf.h", "-I", fw, "-f", "Complementary1D", "--init",
             "cf_init", "--update", "cf_update", "--state", "theta=theta", "--plot", src)
    assert p.returncode == 2 and "is the input" in p.stderr, p.stderr
    _unchanged(src, before)


def test_a_failed_write_leaves_the_previous_file(tmp_path):
    out = tmp_path / "out.csv"
    out.write_text("the previous output\n")
    with pytest.raises(RuntimeError):
        with replacing(out) as tmp:
            with open(tmp, "w") as fh:
                fh.write("half of the new")
            raise RuntimeError("disk full")
    assert out.read_text() == "the previous output\n"
    assert sorted(os.listdir(tmp_path)) == ["out.csv"]          # no temporary left


def test_a_file_size_limit_leaves_the_previous_output(tmp_path, log):
    """RLIMIT_FSIZE in the child: the CSV cannot be written whole; the old one stays."""
    out = tmp_path / "out.csv"
    out.write_text("the previous output\n")
    code = ("import resource, signal, sys; signal.signal(signal.SIGXFSZ, signal.SIG_IGN); "
            "resource.setrlimit(resource.RLIMIT_FSIZE, (20000, 20000)); "
            "from imufuse.cli import main; sys.exit(main(sys.argv[1:]))")
    p = subprocess.run([sys.executable, "-c", code, "run", str(log), "-f", "MadgwickIMU", "-o",
                        str(out)], capture_output=True, text=True)
    assert p.returncode == 3, p.stderr
    assert out.read_text() == "the previous output\n"
    assert sorted(os.listdir(tmp_path)) == ["log.csv", "out.csv"]


def test_permissions_of_a_replaced_file_are_kept(tmp_path):
    out = tmp_path / "o.csv"
    out.write_text("x\n")
    os.chmod(out, 0o640)
    io.write_csv(str(out), {"a": np.arange(3.0)})
    assert os.stat(out).st_mode & 0o777 == 0o640 and out.read_text().startswith("a\n")


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full on this system")
def test_a_device_is_written_in_place_never_replaced(log):
    import stat
    assert stat.S_ISCHR(os.stat(os.devnull).st_mode) and stat.S_ISCHR(os.stat("/dev/full").st_mode)
    p = _cli("run", log, "-f", "MadgwickIMU", "-o", "/dev/full")
    assert p.returncode == 3 and "cannot write" in p.stderr
    assert stat.S_ISCHR(os.stat("/dev/full").st_mode)
    p = _cli("run", log, "-f", "MadgwickIMU", "-o", os.devnull)
    assert p.returncode == 0, p.stderr
    assert stat.S_ISCHR(os.stat(os.devnull).st_mode)
