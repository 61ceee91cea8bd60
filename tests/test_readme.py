"""The README's Python examples run as written, and its interactive examples
print what the README says (documentation matches the code)."""
import doctest
import os
import re

import pytest

README = open(os.path.join(os.path.dirname(__file__), "..", "README.md")).read()
BLOCKS = re.findall(r"```python\n(.*?)```", README, re.S)


def test_readme_has_examples():
    assert len(BLOCKS) >= 3


@pytest.mark.parametrize("code", BLOCKS, ids=[f"block{i}" for i in range(len(BLOCKS))])
def test_readme_example_runs(code):
    if code.lstrip().startswith(">>>"):
        test = doctest.DocTestParser().get_doctest(code, {}, "README", "README.md", 0)
        runner = doctest.DocTestRunner(optionflags=doctest.NORMALIZE_WHITESPACE)
        runner.run(test)
        assert runner.summarize(verbose=False).failed == 0
    else:
        exec(compile(code, "README.md", "exec"), {})


def _three_d():
    from imufuse import catalogue
    return [e for e in catalogue.FLOAT if e.kind in ("imu", "ahrs")]


@pytest.mark.parametrize("e", _three_d(), ids=lambda e: e.name)
def test_readme_python_example_runs_for_every_3d_filter(e):
    """The README's first Python example with its filter replaced by each 3-D filter of the
    catalogue at its defaults (IMU filters without the magnetometer): it runs as written,
    evaluate() takes run(..., outputs="q") of every one, and the error is that of the
    quaternion the filter estimates, computed here independently from its state."""
    from imufuse import io
    from imufuse.evaluation import evaluate
    import imufuse_c
    code = next(b for b in BLOCKS if "MadgwickAHRS(dt=log.dt" in b)
    line = next(ln for ln in code.splitlines() if "MadgwickAHRS(dt=log.dt" in ln)
    kw = "".join(f", {k}={v!r}" for k, v in e.defaults.items())
    new = line.split("=", 1)[0] + f"= imufuse_c.{e.name}(dt=log.dt, init=\"first\"{kw})"
    code = code.replace(line, new)
    if e.kind == "imu":
        code = code.replace("log.gyr, log.acc, log.mag,", "log.gyr, log.acc,")
    code = code.replace("e.inclination < 5", "e.inclination < 180")
    ns = {}
    exec(compile(code, "README.md", "exec"), ns)
    log = io.read_log(io.example_log())
    f = getattr(imufuse_c, e.name)(dt=log.dt, init="first", **e.defaults)
    ins = (log.gyr, log.acc) if e.kind == "imu" else (log.gyr, log.acc, log.mag)
    states = f.run(*ins)
    from imufuse import catalogue
    q = catalogue.estimate(type(f), states).q
    want = evaluate(q, log.q_ref, est_frame="NWU", ref_frame="ENU", movement=log.movement)
    assert ns["e"].inclination == want.inclination and ns["e"].n == want.n > 0


def test_run_outputs_are_refused_where_they_do_not_exist():
    import imufuse_c
    from imufuse import reference
    for mod in (imufuse_c, reference):
        with pytest.raises(ValueError, match="outputs: must be one of"):
            mod.MadgwickIMU(0.01).run([[0, 0, 0]], [[0, 0, 1]], outputs="quaternion")
        with pytest.raises(ValueError, match="outputs"):
            mod.Mahony1D(0.01, kp=1.0).run([0.0], [0.0], outputs="q")
    from imufuse.evaluation import evaluate
    s = imufuse_c.RobustAHRS(0.01).run([[0, 0, 0]], [[0, 0, 1]], [[1, 0, 0]])
    with pytest.raises(ValueError, match=r"outputs='q'"):
        evaluate(s, [[1.0, 0, 0, 0]])
