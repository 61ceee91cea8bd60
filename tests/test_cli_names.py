"""Command-line polish: --version, filter names in any case with suggestions from the listed
names, help for users (no developer notes), and validate without cffi naming the extra."""
import os
import subprocess
import sys

import numpy as np
import pytest

import imufuse
from imufuse import catalogue
from imufuse.io import example_log
from cli_here import imf_here


def _cli(*args):
    """The command line through main() in this process (its messages and exit codes)."""
    return imf_here(*args)


def test_version():
    p = _cli("--version")
    assert p.returncode == 0 and p.stdout.strip() == f"imufuse {imufuse.__version__}"


def test_help_is_for_users():
    p = _cli("--help")
    assert p.returncode == 0 and "Adding a subcommand" not in p.stdout and "export" in p.stdout


@pytest.mark.parametrize("given", ["madgwickahrs", "MADGWICKAHRS", "MadgwickAHRS"])
def test_filter_names_in_any_case(tmp_path, given):
    p = _cli("run", example_log(), "-f", given, "--dtype", "float32", "-o", str(tmp_path / "o.npz"))
    assert p.returncode == 0, p.stderr
    assert "MadgwickAHRS (c, float32" in p.stderr


def test_suggestions_come_from_the_listed_names():
    with pytest.raises(catalogue.FilterError) as e:
        catalogue.entry("madgwikahrs")
    msg = str(e.value)
    assert "did you mean MadgwickAHRS" in msg
    hinted = msg.split("did you mean ")[1].split("?")[0].split(", ")
    listed = msg.split("valid filters: ")[1].replace("; fixed point: ", ", ").split(", ")
    assert set(hinted) <= set(listed)
    assert catalogue.canonical_name("mahonyimuq") == "MahonyIMUQ"
    assert catalogue.canonical_name("nosuchfilter") == "nosuchfilter"


def test_validate_without_cffi_names_the_extra(tmp_path):
    """cffi hidden from the interpreter: exit 5 with the extra to install, not an internal error."""
    (tmp_path / "cffi.py").write_text("raise ImportError('cffi hidden by the test')\n")
    code = ("import sys; from imufuse.cli import main; "
            "sys.exit(main(['validate', '--csrc', '-f', 'Kalman1D', '--duration', '1']))")
    env = {**os.environ, "IMUFUSE_CACHE": str(tmp_path / "cache"),   # nothing built before
           # the fake cffi ahead of the real one
           "PYTHONPATH": os.pathsep.join(filter(None, [str(tmp_path), os.environ.get("PYTHONPATH")]))}
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert p.returncode == 5, p.stderr
    assert "pip install 'imufuse[firmware]'" in p.stderr and "internal error" not in p.stderr


def test_preset_on_the_command_line(tmp_path):
    """--preset published runs the published settings (the defaults' bits where they are the
    same), --param applies on top of it, and an unknown preset is a usage error naming
    the presets."""
    from imufuse.io import example_log
    log = example_log()

    def run(*extra):
        out = tmp_path / f"o{len(list(tmp_path.iterdir()))}.npz"
        p = subprocess.run([sys.executable, "-m", "imufuse", "run", log, "-f", "MahonyAHRS",
                            "-o", str(out), *extra], capture_output=True, text=True)
        return p, out
    p0, o0 = run()
    p1, o1 = run("--preset", "published")
    p2, o2 = run("--preset", "published", "-p", "ki=0.05")
    assert p0.returncode == p1.returncode == p2.returncode == 0, p2.stderr
    a, b, c = (np.load(o)["q0"] for o in (o0, o1, o2))
    assert np.array_equal(a, b) and not np.array_equal(b, c)
    assert "kp=0.5, ki=0.05" in p2.stderr
    p, _ = run("--preset", "nope")
    assert p.returncode == 2 and "no preset 'nope'; presets: published" in p.stderr, p.stderr


def test_tune_and_latency_take_the_preprocessing(tmp_path):
    """--align (and --calibration, --offset) in front of tune and latency as of run and compare:
    the shipped excerpt with its sensor axes turned (sensor x = body y, sensor y = -body x)
    gives tune's table and latency's delay of the excerpt itself with --align -Y+X+Z, and
    latency refuses it without (the rates do not follow the reference's)."""
    import numpy as np
    from imufuse import io
    src = io.example_log()
    d = dict(np.load(src))
    for k in ("gyr", "acc", "mag"):
        v = d[k]
        d[k] = np.stack([v[:, 1], -v[:, 0], v[:, 2]], axis=1)
    turned = tmp_path / "turned.npz"
    np.savez(turned, **d)

    def tail(*args):
        # what was printed, the log's name aside (in the tables' headers and rules)
        p = _cli(*args)
        assert p.returncode == 0, p.stderr
        out = p.stdout.replace(str(turned), "LOG").replace(src, "LOG")
        return [ln.split() for ln in out.splitlines()
                if "npz" not in ln and not set(ln.strip()) <= {"-"}]

    # as typed, the value apart (it starts with a minus: not an option) and joined
    assert tail("latency", str(turned), "--align", "-Y+X+Z") == tail("latency", src)
    p = _cli("latency", str(turned))
    assert p.returncode != 0 and "does not follow the reference's rates" in p.stderr, p.stderr
    grid = ("-f", "MadgwickIMU", "--grid", "beta=0.05,0.1", "--refine", "0", "-q")
    assert tail("tune", str(turned), *grid, "--align=-Y+X+Z") == tail("tune", src, *grid)


def test_compare_refuses_a_parameter_value_as_run_does():
    """A value given with -p that the filter refuses is the user's mistake: compare left the
    filter out of the table ("skipped: ...") and exited 0 beside another filter, or 4 ("no
    filter could run on this log") alone, where run exits 2 naming the value."""
    for fl in ("RobustIMU", "RobustIMU,MadgwickIMU"):
        r = imf_here("compare", example_log(), "-f", fl, "-p", "RobustIMU.latency=-0.0025")
        assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
        assert "RobustIMU: latency: must be finite and 0.0 <= latency <= 0.1, got -0.0025" \
            in r.stderr, r.stderr
    r = imf_here("compare", example_log(), "-f", "RobustIMU,MadgwickIMU", "-p",
                 "RobustIMU.latency=0.002")
    assert r.returncode == 0 and "skipped" not in r.stdout, r.stdout


def test_compare_help_names_the_fusion_it_runs():
    """compare --help said its default includes "FusionAHRS" (the 1.2.3 port); the table
    runs FusionAHRS13."""
    text = " ".join(imf_here("compare", "--help").stdout.split())
    assert "x-io Fusion's current release (FusionAHRS13; FusionAHRS, its 1.2.3 port, when " \
           "named)" in text, text
    r = imf_here("compare", example_log())
    assert r.returncode == 0, r.stderr
    rows = {ln.split()[0] for ln in r.stdout.splitlines() if ln.startswith("Fusion")}
    assert rows == {"FusionAHRS13"}, r.stdout
