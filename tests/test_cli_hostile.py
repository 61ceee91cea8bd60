"""The command line under hostile arguments and hostile files: every failure
is a one-line message with its documented exit code, never a traceback; the
input log is never overwritten; `compare` never exits 0 having computed
nothing; `validate` survives crashing, exiting and hanging firmware."""
import os
import re
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import imufuse
import imufuse_c
from imufuse import io, sim
from cli_here import imf_here

PATHS = [os.path.dirname(os.path.dirname(imufuse.__file__)),
         os.path.dirname(os.path.dirname(imufuse_c.__file__))]
# the exit codes documented in imufuse.cli
OK, FAIL, USAGE, FILE, DATA, FIRMWARE = 0, 1, 2, 3, 4, 5


def imf(*args, cwd=None, env=None, timeout=120):
    e = dict(os.environ)
    e["PYTHONPATH"] = os.pathsep.join(PATHS + [e.get("PYTHONPATH", "")])
    e["MPLBACKEND"] = "Agg"
    e.pop("IMUFUSE_DEBUG", None)
    e.update(env or {})
    return subprocess.run([sys.executable, "-m", "imufuse", *map(str, args)], cwd=cwd, env=e,
                          capture_output=True, text=True, timeout=timeout)


def one_line_error(r, code):
    """Exit `code`, no traceback, and the failure said in one line."""
    assert r.returncode == code, (r.returncode, r.stdout[-2000:], r.stderr[-2000:])
    assert "Traceback" not in r.stderr and "Traceback" not in r.stdout, r.stderr
    errs = [ln for ln in r.stderr.splitlines() if ln.startswith("imufuse: error:")
            or ln.startswith("imufuse: internal error")]
    assert len(errs) == 1, r.stderr
    assert "internal error" not in errs[0], errs[0]
    return errs[0]


HEAD = "time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n"


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("hostile")
    data = sim.imu("slow", rate=100.0, duration=2.0, seed=3)
    good = d / "good.csv"
    io.write_log(good, data.t, data.gyr, data.acc, data.mag, data.q_true)
    f = {"good": good}

    def w(name, text, mode="w"):
        p = d / name
        with open(p, mode) as fh:
            fh.write(text)
        f[name] = p

    w("empty.csv", "")
    w("header_only.csv", HEAD)
    w("abc.csv", "a,b,c\n1,2,3\n4,5,6\n")
    w("binary.csv", bytes(range(256)) * 10, "wb")
    w("latin1.csv", HEAD.encode() + "0,1,2,3,4,5,\xe9\n".encode("latin-1") * 3, "wb")
    w("times_overflow.csv", HEAD + "-1e308,0,0,0,0,0,1\n1e308,0,0,0,0,0,1\n")
    w("time_nan.csv", HEAD + "0,0,0,0,0,0,1\nnan,0,0,0,0,0,1\n")
    w("one_row.csv", HEAD + "0,0,0,0,0,0,1\n")
    w("long_field.csv", HEAD + "0,0,0,0,0,0,1\n0.01,0," + "7" * 140000 + ",0,0,0,1\n")
    w("long_text.csv", HEAD + "0,0,0,0,0,0,1\n0.01,0," + "x" * 140000 + ",0,0,0,1\n")
    w("short_row.csv", HEAD + "0,0,0,0,0,0,1\n0.01,0,0\n")
    w("cut_short.csv", HEAD + "0,0,0,0,0,0,1\n0.01,0,0,0,0,0,1\n0.02,0,0,0,0")
    w("empty_field.csv", HEAD + "0,0,0,0,0,0,1\n0.01,0,,0,0,0,1\n")
    w("quote.csv", HEAD + '0,0,0,0,0,0,1\n0.01,"0,0,0,0,0,1\n')
    w("rate_angle.csv", "time,rate,angle\n" + "".join(f"{k / 100},0.1,0.2\n" for k in range(50)))
    nanref = d / "nanref.csv"
    q = data.q_true.copy()
    q[:] = np.nan
    io.write_log(nanref, data.t, data.gyr, data.acc, data.mag, q)
    f["nanref.csv"] = nanref
    os.mkdir(d / "adir")
    f["adir"] = d / "adir"
    return f


@pytest.mark.parametrize("name,extra,code,word", [
    ("empty.csv", [], DATA, "empty file"),
    ("header_only.csv", [], DATA, "no data rows"),
    ("abc.csv", [], DATA, "no known column"),
    ("binary.csv", [], DATA, "not a text"),
    ("latin1.csv", [], DATA, "UTF-8"),
    ("times_overflow.csv", [], DATA, "not a finite number"),
    ("time_nan.csv", [], DATA, "time is not finite"),
    ("one_row.csv", [], DATA, "one sample"),
    ("long_text.csv", [], DATA, "not a number"),
    ("short_row.csv", [], DATA, ":3:"),
    ("cut_short.csv", [], DATA, ":4: 5 values, the header has 7 columns (the last line, "
     "without a line end: a file cut short"),
    ("empty_field.csv", [], DATA, "not a number: ''"),
    ("quote.csv", [], DATA, "quote.csv"),
    ("adir", [], FILE, "is a directory"),
    ("missing.csv", [], FILE, "no such file"),
    ("good", ["--rate", "1e-300"], USAGE, "--rate"),
    ("good", ["--rate", "nan"], USAGE, "--rate"),
    ("good", ["--rate", "inf"], USAGE, "--rate"),
    ("good", ["--rate", "abc"], USAGE, "--rate"),
    ("good", ["-p", "beta=nan"], USAGE, "beta"),
    ("good", ["-p", "beta=1e400"], USAGE, "beta"),
    ("good", ["-p", "beta=[1,2]"], USAGE, "beta"),
    ("good", ["-p", "beta='x'"], USAGE, "beta"),
    ("good", ["-p", "beta=" + "9" * 5000], USAGE, "beta"),
    ("good", ["--init", "north"], USAGE, "--init"),
    ("good", ["--init", "0,0,0,0"], USAGE, "--init"),
    ("good", ["--columns", "gyro_x=foo"], USAGE, "not a log column"),
    ("good", ["--columns", "gyr_x"], USAGE, "NAME=HEADER"),
    ("good", ["--columns", "gyr_x=nothere"], DATA, "no such column"),
    ("good", ["--column-map", "/nonexistent/map.txt"], FILE, "map.txt"),
    ("good", ["--ref-frame", "XYZ"], USAGE, "--ref-frame"),
    ("good", ["--filter", "Nope"], USAGE, "unknown filter"),
])
def test_hostile_files_and_arguments(files, tmp_path, name, extra, code, word):
    log = files.get(name, tmp_path / name)
    args = ["run", log, "-o", tmp_path / "out.csv"] + extra
    if "--filter" not in extra:
        args += ["-f", "MadgwickIMU"]
    line = one_line_error(imf_here(*args), code)
    assert word in line, line


def test_the_entry_point_says_the_same_in_its_own_process(files, tmp_path):
    """One of the hostile files through a new interpreter (`python -m imufuse`): the same
    line and exit code as main() in this process."""
    args = ["run", files["abc.csv"], "-o", tmp_path / "out.csv", "-f", "MadgwickIMU"]
    assert one_line_error(imf(*args), DATA) == one_line_error(imf_here(*args), DATA)


def test_long_numeric_field_is_a_number(files, tmp_path):
    """A 140000-digit number is read (as inf: the filter skips the sample)."""
    r = imf_here("run", files["long_field.csv"], "-f", "MadgwickIMU", "-o", tmp_path / "o.csv",
            "--rate", 100)
    assert r.returncode == 0, r.stderr
    assert "Traceback" not in r.stderr


@pytest.mark.parametrize("how", ["same", "relative", "symlink", "hardlink"])
def test_output_is_never_the_input(files, tmp_path, how):
    src = tmp_path / "log.csv"
    src.write_bytes(files["good"].read_bytes())
    before = src.read_bytes()
    out = {"same": src, "relative": "log.csv"}.get(how)
    if how == "symlink":
        out = tmp_path / "link.csv"
        os.symlink(src, out)
    elif how == "hardlink":
        out = tmp_path / "hard.csv"
        os.link(src, out)
    for cmd in (["run", src, "-f", "MadgwickIMU", "-o", out],
                ["run", src, "-f", "MadgwickIMU", "--plot", out],
                ["compare", src, "--plot", out]):
        line = one_line_error(imf_here(*cmd, cwd=tmp_path), USAGE)
        assert "refusing to overwrite" in line
    assert src.read_bytes() == before


@pytest.mark.parametrize("out,word", [
    ("missing-dir/out.csv", "does not exist"),
    ("@dir", "is a directory"),
    ("/dev/full", "cannot write"),
    ("new-dir/", "names a directory (the final '/'), which does not exist"),
    ("", "-o: an empty file name"),
])
def test_unwritable_outputs(files, tmp_path, out, word):
    """A missing directory, a directory, a full device; a name ending in '/' (a directory
    meant: the file was written as the name without the slash, exit 0) and an empty name
    (it read "cannot write: Is a directory")."""
    out = (tmp_path if out == "@dir" else out if out.startswith("/") or not out
           else str(tmp_path / out) + ("/" if out.endswith("/") else ""))
    if str(out) == "/dev/full" and not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full on this system")
    line = one_line_error(imf_here("run", files["good"], "-f", "MadgwickIMU", "-o", out,
                                   cwd=tmp_path), FILE)
    assert word in line
    assert not (tmp_path / "new-dir").exists()


@pytest.mark.parametrize("args,word", [
    (["bench", "--ref-samples", "0"], "--ref-samples"),
    (["bench", "--samples", "1e12"], "--samples: expected an integer, got '1e12'"),  # "a int"
    (["bench", "--samples", "0"], "--samples: must be > 0 and at most 1e+08, got 0"),
    (["bench", "--repeat", "0"], "--repeat"),
    (["bench", "--samples", "-1"], "--samples"),
    (["demo", "--duration", "0"], "--duration"),
    (["tune", "@good", "-f", "MadgwickIMU", "--grid", "beta=1:2"], "--grid"),
    (["tune", "@good", "-f", "Kalman1D"], "single-axis"),
    (["nosuchcommand"], "invalid choice"),
])
def test_hostile_subcommand_arguments(files, args, word):
    args = [str(files[a[1:]]) if a.startswith("@") else a for a in args]
    r = imf_here(*args)
    assert r.returncode == USAGE, r.stderr
    assert "Traceback" not in r.stderr and word in r.stderr


def test_compare_falls_back_to_single_axis_filters(files):
    r = imf_here("compare", files["rate_angle.csv"])
    assert r.returncode == 0, r.stderr
    from imufuse.reference import FILTERS_1D
    for n in FILTERS_1D:
        assert any(ln.startswith(n + " ") for ln in r.stdout.splitlines()), r.stdout


def test_compare_computing_nothing_fails(files):
    one_line_error(imf_here("compare", files["abc.csv"], "--rate", 100), DATA)
    line = one_line_error(imf_here("compare", files["nanref.csv"]), DATA)
    assert "nothing could be evaluated" in line
    line = one_line_error(imf_here("compare", files["good"], "-f", "MahonyAHRS", "--columns",
                              "mag_x=time,mag_y=time,mag_z=time", "-f", "Kalman1D",
                              "--axis", "y", "--columns", "gyr_y=acc_x"), OK) \
        if False else None
    # an AHRS filter alone on a log without a magnetometer: nothing computed
    noq = files["good"].parent / "nomag.csv"
    d = sim.imu("static", rate=100.0, duration=1.0, seed=1)
    io.write_log(noq, d.t, d.gyr, d.acc)
    line = one_line_error(imf_here("compare", noq, "-f", "MahonyAHRS"), DATA)
    assert "no filter could run" in line


# ---------------------------------------------------------------------------
# validate: the firmware runs isolated, with a timeout

FW_H = textwrap.dedent("""
    typedef struct { struct { float theta; } x; float dt; int k; } fw_t;
    void fw_init(fw_t *s, float dt, float k0);
    void fw_update(fw_t *s, float rate, float angle);
""")
FW = textwrap.dedent("""
    #include <stdlib.h>
    #include "fw.h"
    void fw_init(fw_t *s, float dt, float k0) { (void)k0; s->dt = dt; s->k = 0; INIT_HOOK; }
    void fw_update(fw_t *s, float rate, float angle) {
        (void)angle;
        if (s->k == 7) { UPDATE_HOOK; }
        s->k++;
        s->x.theta += rate * s->dt;
    }
""")


@pytest.fixture(scope="module")
def fw_env(tmp_path_factory):
    return {"IMUFUSE_CACHE": str(tmp_path_factory.mktemp("fw-cache"))}


@pytest.mark.parametrize("init,update,word", [
    ("(void)0", "volatile int *p = 0; *p = 1", "crashed with SIGSEGV at sample 7"),
    ("abort()", "(void)0", "crashed with SIGABRT during init"),
    ("(void)0", "exit(3)", "called exit(3) at sample 7"),
    ("(void)0", "for (;;) {}", "no answer after 3 s"),
    ("(void)0", "extern void not_defined_anywhere(void); not_defined_anywhere()",
     "symbol not found: not_defined_anywhere"),
])
def test_validate_isolates_the_firmware(tmp_path, fw_env, init, update, word):
    src = tmp_path / "fw.c"
    src.write_text(FW.replace("INIT_HOOK", init).replace("UPDATE_HOOK", update))
    (tmp_path / "fw.h").write_text(FW_H)
    r = imf("validate", src, "-I", tmp_path, "--header", "fw.h", "-f", "Kalman1D", "--init",
            "void fw_init(fw_t *s, float dt, float k0)",
            "--update", "void fw_update(fw_t *s, float rate, float angle)",
            "--duration", 1, "--timeout", 3, env=fw_env, timeout=120)
    line = one_line_error(r, FIRMWARE)
    assert word in line, line


def test_validate_integer_state_is_not_compared_as_float(tmp_path, fw_env):
    src = tmp_path / "fwi.c"
    (tmp_path / "fwi.h").write_text("typedef struct { struct { int theta; } x; } fw_t;\n"
                                    "void fw_update(fw_t *s, float rate, float angle);\n")
    src.write_text(textwrap.dedent("""
        #include "fwi.h"
        void fw_update(fw_t *s, float rate, float angle) { s->x.theta += (int)(rate * 100); (void)angle; }
    """))
    r = imf("validate", src, "-I", tmp_path, "--header", "fwi.h", "-f", "Kalman1D",
            "--update", "void fw_update(fw_t *s, float rate, float angle)",
            "--duration", 1, env=fw_env)
    line = one_line_error(r, FIRMWARE)
    assert "integer" in line and "int32" in line


def test_integer_trajectories_compare_as_integers():
    from imufuse.firmware import compare_states
    a = np.array([[1], [2], [3]], dtype=np.int32)
    b = a.copy()
    assert compare_states(a, b).bit_exact
    b[2, 0] = 4
    rep = compare_states(a, b)
    assert not rep.bit_exact and rep.first_sample == 2 and rep.max_abs["s0"] == 1


def test_a_closed_pipe_is_not_an_error(tmp_path):
    """`imufuse run log.csv | head -1`: exit 0, nothing on stderr about the pipe."""
    d = sim.imu("slow", rate=200.0, duration=60.0, seed=2)
    log = tmp_path / "long.csv"
    io.write_log(log, d.t, d.gyr, d.acc)
    e = dict(os.environ, PYTHONPATH=os.pathsep.join(PATHS))
    p = subprocess.Popen([sys.executable, "-m", "imufuse", "run", str(log), "-f", "MadgwickIMU"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=e, text=True)
    assert p.stdout.readline().startswith("time,")
    p.stdout.close()
    err = p.stderr.read()
    assert p.wait(timeout=120) == 0, err
    assert "Traceback" not in err and "Exception ignored" not in err and "Broken" not in err


def test_skip_leaves_the_start_out_of_the_errors(files):
    """--skip S: the first S seconds do not count (counted as outside the mask)."""
    a = imf_here("compare", files["good"], "-f", "MadgwickIMU")
    b = imf_here("compare", files["good"], "-f", "MadgwickIMU", "--skip", 1)
    assert a.returncode == b.returncode == 0, a.stderr + b.stderr
    na = int(next(ln for ln in a.stdout.splitlines() if ln.startswith("MadgwickIMU ")).split()[5])
    nb = int(next(ln for ln in b.stdout.splitlines() if ln.startswith("MadgwickIMU ")).split()[5])
    t = io.read_log(files["good"]).t
    assert na == len(t) and nb == int(np.count_nonzero(t >= t[0] + 1))
    assert f"{na - nb} samples outside the movement mask" in b.stdout


@pytest.mark.parametrize("cmd", ["run", "compare", "tune"])
def test_a_skip_past_the_end_is_said(files, tmp_path, cmd):
    """--skip beyond the log's end: run wrote its output and printed 'total nan ... (outside
    the movement mask)' with exit 0, compare blamed the reference and the mask, tune said
    only 'no parameter set could be evaluated'. Now exit 4 naming --skip and the log's
    length, before anything is written."""
    args = {"run": ["-f", "MadgwickIMU", "-o", tmp_path / "o.csv"],
            "compare": ["-f", "MadgwickIMU"], "tune": ["-f", "MadgwickIMU", "-q"]}[cmd]
    line = one_line_error(imf_here(cmd, files["good"], "--skip", 100, *args), DATA)
    assert "--skip 100 s leaves no sample: the log lasts 1.99 s" in line, line
    assert not (tmp_path / "o.csv").exists()


@pytest.mark.parametrize("cmd,name,extra,code", [
    ("compare", "binary.csv", [], DATA),
    ("compare", "missing.csv", [], FILE),
    ("compare", "good", ["-f", "Nope"], USAGE),
    ("compare", "good", ["--plot", "/nonexistent-dir/p.png"], FILE),
    ("compare", "times_overflow.csv", [], DATA),
    ("tune", "adir", ["-f", "MadgwickIMU"], FILE),
    ("tune", "missing.csv", ["-f", "MadgwickIMU"], FILE),
    ("tune", "empty.csv", ["-f", "MadgwickIMU"], DATA),
    ("tune", "good", ["-f", "MadgwickIMU", "--grid", "beta=-1:1:3"], USAGE),
    ("tune", "good", ["-f", "MadgwickIMU", "--grid", "gamma=0.1,0.2", "-q"], USAGE),
    ("validate", "good", ["-f", "Kalman1D", "--csrc", "/nonexistent"], FILE),
    ("validate", "good", ["-f", "Kalman1D", "--timeout", "0"], USAGE),
])
def test_hostile_compare_tune_validate(files, tmp_path, cmd, name, extra, code):
    log = files.get(name, tmp_path / name)
    args = [cmd] + ([log] if cmd != "validate" else ["--log", log]) + extra
    one_line_error(imf_here(*args), code)


def test_block_estimates_equal_whole_ones():
    """The command line derives estimates block by block (long logs stay small
    in memory): the same values as one catalogue.estimate call, every filter."""
    from imufuse.catalogue import estimate, filter_names, reference_class, resolve_params
    from imufuse.session import chunked_estimate
    d = sim.imu("slow", rate=200.0, duration=30.0, seed=3)
    for n in filter_names():
        cls = reference_class(n)
        ins = {"1d": (d.gyr[:, 0], np.arctan2(d.acc[:, 1], d.acc[:, 2])),
               "imu": (d.gyr, d.acc), "ahrs": (d.gyr, d.acc, d.mag)}[cls.kind]
        S = getattr(imufuse_c, n)(**resolve_params(n, d.dt)).run(*ins)
        a, b = estimate(cls, S), chunked_estimate(cls, S, chunk=997)
        x, y = (a.angle, b.angle) if a.angle is not None else (a.q, b.q)
        assert np.array_equal(x, y), n


@pytest.mark.parametrize("cmd", ["run", "compare"])
def test_a_log_without_samples_is_a_data_error(tmp_path, cmd):
    """An NPZ whose arrays have 0 rows: exit 4 naming the file (compare ended in an
    internal error, run wrote an empty output with exit 0)."""
    p = tmp_path / "zero.npz"
    np.savez(p, gyr=np.zeros((0, 3)), acc=np.zeros((0, 3)), rate=100.0)
    extra = ["-f", "MadgwickIMU", "-o", str(tmp_path / "o.csv")] if cmd == "run" else []
    r = imf_here(cmd, str(p), *extra)
    assert r.returncode == 4 and "zero.npz: no samples" in r.stderr, r.stderr
    assert not (tmp_path / "o.csv").exists()


def test_two_columns_of_one_name_are_a_data_error(tmp_path):
    """A header naming gyr_x twice: which one the filter reads is not the reader's guess."""
    p = tmp_path / "dup.csv"
    p.write_text("time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,gyr_x\n"
                 + "".join(f"{k / 100},0,0,0,0,0,1,5\n" for k in range(5)))
    r = imf_here("run", str(p), "-f", "MadgwickIMU", "-o", str(tmp_path / "o.csv"))
    assert r.returncode == 4 and "columns 2 and 8 are both gyr_x" in r.stderr, r.stderr


def test_rejected_samples_are_reported(tmp_path):
    """A log whose every sample is NaN: run and compare exit 4 saying every sample was
    rejected (they printed "20 samples" and scores of 0.00 with exit 0); a log with some
    rejected samples gets a note with their count."""
    p = tmp_path / "nan.csv"
    p.write_text("time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n"
                 + "".join(f"{k / 100},nan,0,0,0,0,1\n" for k in range(20)))
    r = imf_here("run", str(p), "-f", "MadgwickIMU", "-o", str(tmp_path / "o.csv"))
    assert r.returncode == 4 and "rejected every one of the 20 samples" in r.stderr, r.stderr
    r = imf_here("compare", str(p), "-f", "MadgwickIMU")
    assert r.returncode == 4 and "every one of the 20 samples rejected" in r.stderr, r.stderr
    q = tmp_path / "some.csv"
    q.write_text("time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n"
                 + "".join(f"{k / 100},{'nan' if k in (5, 9) else 0},0,0,0,0,1\n"
                           for k in range(20)))
    r = imf_here("run", str(q), "-f", "MadgwickIMU", "--init", "identity", "-o",
            str(tmp_path / "o.csv"))
    assert r.returncode == 0 and "note: 2 of 20 samples rejected by MadgwickIMU" in r.stderr, \
        r.stderr


def test_vario_and_calibrate_bad_files_are_data_errors(tmp_path):
    """A binary file, a log of another encoding, a vario log without two usable barometer
    samples: exit 4 naming the file (they exited 2, "bad command line", with a codec
    message); the same message as `imufuse run` gives, since every command reads logs
    through the session."""
    binary = tmp_path / "bin.csv"
    binary.write_bytes(bytes(range(128, 256)) * 4)
    latin = tmp_path / "latin.csv"
    latin.write_bytes("time,gyr_x (\xb0/s),gyr_y,gyr_z\n0,1,2,3\n".encode("latin-1"))
    for f in (binary, latin):
        r = imf_here("run", f, "-f", "MadgwickIMU", "-o", tmp_path / "r.csv")
        said = r.stderr.strip()
        assert r.returncode == 4 and f"{f}: not UTF-8 text at byte" in said, said
        r = imf_here("vario", f, "-o", tmp_path / "v.csv")
        assert r.returncode == 4 and r.stderr.strip() == said, r.stderr
        r = imf_here("calibrate", "gyro", f, "-o", tmp_path / "c.json")
        assert r.returncode == 4 and r.stderr.strip() == said, r.stderr
    nobaro = tmp_path / "nobaro.csv"
    nobaro.write_text("time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,pressure\n"
                      + "".join(f"{k / 100},0,0,0,0,0,1,{'' if k else 'nan'}\n"
                                for k in range(50)))
    r = imf_here("vario", nobaro, "-o", tmp_path / "v.csv")
    assert r.returncode == 4 and "0 usable barometer samples in column pressure" in r.stderr, \
        r.stderr
    assert not (tmp_path / "v.csv").exists()


def test_calibrate_a_one_row_log_says_what_calibration_needs(files, tmp_path):
    """calibrate needs no time: a log of one row with a time column was refused with "give
    --rate", an option calibrate does not have; the calibration's own need is said."""
    r = imf_here("calibrate", "gyro", files["one_row.csv"], "-o", tmp_path / "c.json")
    line = one_line_error(r, DATA)
    assert "gyr: need at least 100 samples, got 1" in line and "--rate" not in line, line


@pytest.mark.parametrize("pressure,msg", [
    ("1e308", "median 1e[+]308 Pa is not an air pressure"),
    ("1013.25", "it looks like hPa: write the header 'pressure [(]hPa[)]'"),
    ("-5", "median -5 Pa is not an air pressure")])
def test_vario_absurd_pressures_are_data_errors(tmp_path, pressure, msg):
    """Finite but absurd pressures (1e308 Pa gave an altitude of -2e62 m, exit 0) and hPa
    logged as Pa: exit 4 naming the column and the fix."""
    p = tmp_path / "p.csv"
    p.write_text("time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,pressure\n"
                 + "".join(f"{k / 100},0,0,0,0,0,1,{pressure if k % 4 == 0 else ''}\n"
                           for k in range(200)))
    r = imf_here("vario", p, "-o", tmp_path / "v.csv")
    assert r.returncode == 4 and re.search(msg, r.stderr), r.stderr


def test_vario_all_rejected_accelerometer_is_a_data_error(tmp_path):
    """NaN accelerometer readings: every barometer sample rejected by the Kalman filter; it
    reported an altitude of 0.00 m with exit 0 while the barometer said +41 m."""
    p = tmp_path / "n.csv"
    p.write_text("time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,pressure\n"
                 + "".join(f"{k / 100},0,0,0,nan,nan,nan,{101325 - k if k % 4 == 0 else ''}\n"
                           for k in range(200)))
    r = imf_here("vario", p, "-o", tmp_path / "v.csv")
    assert r.returncode == 4 and "rejected every one of the 50 barometer samples" in r.stderr, \
        r.stderr


def test_a_row_with_more_values_than_the_header_is_a_data_error(tmp_path):
    """A row of 13 values under a header of 10 columns (a shifted or damaged row): its first
    columns would be read as gyro and accelerometer from the wrong fields; exit 4 naming the
    line (it was read silently)."""
    p = tmp_path / "long.csv"
    rows = ["0.0,0.01,0.02,0.0,0.0,0.0,1.0,0.3,0.0,-0.5"] * 20
    rows[9] = "0.09,9,9,9,0.01,0.02,0.0,0.0,0.0,1.0,0.3,0.0,-0.5"
    p.write_text("time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,mag_x,mag_y,mag_z\n"
                 + "".join(r.replace("0.0,", f"{k / 100},", 1) + "\n" for k, r in enumerate(rows)))
    r = imf_here("run", p, "-f", "MadgwickIMU", "-o", tmp_path / "o.csv")
    assert r.returncode == 4 and "line 11: 13 values under a header of 10 columns" in r.stderr, \
        r.stderr
