"""Shared pytest configuration (the test helpers are on sys.path through
pyproject.toml: [tool.pytest.ini_options] pythonpath).

Markers (pyproject.toml), given here by module so that a new test in one of these files is
marked without a decorator:

  emulator    runs programs on an emulated MCU (QEMU, simavr)
  crossbuild  compiles with a cross compiler, CMake or builds the package
  fuzz        sanitizers and fuzzers over the C
  slow        all of the above, and the tests that take seconds each (long runs, published-code
              and Fusion oracles, the command line end to end)

The inner loop is `pytest -m "not slow"`; CI runs everything (tools/test.sh). The markers are
checked, not trusted: a test not marked slow that starts an emulator or a compiler (in its own
process: a program it runs, or `python -m imufuse validate` / `setup.py` it runs) fails and
names what it started (_Spawns), so the inner loop stays what README.md says it is.

Workers (pytest-xdist, `--dist loadgroup` in tools/test.sh): the tests of a module that uses
a module- or session-scoped fixture of its own (programs built for an MCU, a built copy of
the package, a fetched oracle) run on one worker, so that the fixture is built once; every
other test goes to whichever worker is free. The groups and the slow tests are handed out
first, the short tests last (pytest_collection_modifyitems).

The firmware builds of a run (validate's programs and host builds) are cached in a directory
of the run's own, $IMUFUSE_CACHE, shared by its workers and removed at its end, never the
user's ~/.cache/imufuse (unless $IMUFUSE_CACHE is set: then there).
"""
import os
import shutil
import subprocess
import sys
import tempfile
import threading

import pytest

EMULATOR = {"test_firmware_target", "test_mcu_filters", "test_mcu_harness", "test_fixed_core_mcu",
            "test_arduino", "test_mcu_cores", "test_firmware_cores", "test_cross_library",
            "test_hil", "test_hil_examples", "test_firmware_declared_target",
            "test_firmware_causes_target", "test_target_cache", "test_firmware_versus",
            "test_declared_hostile"}
CROSSBUILD = {"test_cross_build", "test_cmake_package", "test_build", "test_packaging"}
FUZZ = {"test_sanitizers", "test_sanitizers_batch"}
SLOW = {"test_long_rest", "test_fusion_oracle", "test_published", "test_journeys", "test_cli",
        "test_cli_hostile", "test_outputs_safe", "test_firmware", "test_plausible", "test_frame_hint",
        "test_fusion_cli", "test_cli_names", "test_csv_output", "test_tune", "test_latency",
        "test_reallogs", "test_broad_hdf5", "test_nul_tail", "test_vario_claims",
        "test_calibrate", "test_fixed_accuracy", "test_claims_1d", "test_sim_flight",
        "test_style", "test_header_docs", "test_c_settings", "test_fixed_core", "test_fixed_scale",
        "test_architecture", "test_plots", "test_wheel", "test_firmware_causes",
        "test_firmware_declared", "test_firmware_reports", "test_fixed_update_forms",
        "test_memory"}
# single slow tests in otherwise fast modules (seconds each: a million samples, long bursts)
SLOW_TESTS = {"test_a_million_constant_samples_then_recovery", "test_hostile_burst",
              "test_fusion_ahrs_hostile_burst", "test_first_c_equals_reference",
              "test_hypothesis_sequences", "test_constructors_agree", "test_update_inputs_agree",
              "test_gyro_1e6_rad_s_then_recovery", "test_no_state_write_leaves_a_dead_filter",
              "test_state_held_elsewhere_keeps_its_values", "test_long_rest",
              "test_broad_development_trials", "test_hypothesis_full_int16_range",
              "test_hypothesis_extreme_params_and_states", "test_c_driver_equals_reference",
              # builds with the host's compiler (validate, the fixed-point C drivers, init's
              # refusals compiled)
              "test_a_constructor_runs_only_in_the_child", "test_a_source_that_is_not_c_is_one_line",
              "test_an_edit_of_any_included_file_rebuilds", "test_concurrent_builds_of_one_key",
              "test_the_compiler_is_part_of_the_key", "test_c_driver_exact_axis_readings",
              "test_c_init_refuses_what_the_twin_refuses",
              "test_users_firmware_validated_on_a_published_log", "test_ranges_refused_by_twin_and_c",
              "test_b6_left_out_at_compile_time", "test_a_host_build_is_bounded_and_a_hit_is_a_use"}
# single emulator tests in modules of their own subject
EMULATOR_TESTS = {"test_fusion_ahrs_on_mcu", "test_full_normalisation_from_any_state_on_the_mcu"}


_RUN_CACHE = []


def pytest_configure(config):
    # the run's firmware cache: made by the first process (the controller, before its workers
    # start; they inherit it), removed by it at the end
    if not os.environ.get("IMUFUSE_CACHE"):
        d = tempfile.mkdtemp(prefix="imufuse-test-cache-")
        os.environ["IMUFUSE_CACHE"] = d
        _RUN_CACHE.append(d)


def pytest_unconfigure(config):
    for d in _RUN_CACHE:
        shutil.rmtree(d, ignore_errors=True)


@pytest.hookimpl(tryfirst=True)   # before pytest-xdist's loadgroup reads xdist_group
def pytest_collection_modifyitems(config, items):
    for item in items:
        mod = item.module.__name__.rpartition(".")[2] if item.module else ""
        name = item.originalname or item.name
        marks = set()
        if mod in EMULATOR or name in EMULATOR_TESTS:
            marks.add("emulator")
        if mod in CROSSBUILD:
            marks.add("crossbuild")
        if mod in FUZZ:
            marks.add("fuzz")
        if marks or mod in SLOW or name in SLOW_TESTS:
            marks.add("slow")
        for m in sorted(marks):
            item.add_marker(getattr(pytest.mark, m))
        if _shares_a_fixture(item):
            item.add_marker(pytest.mark.xdist_group(mod))
    # the workers take the work in this order: the groups (a fixture built once, then their
    # tests: tens of seconds on one worker) and the slow tests first, the many short tests
    # after them, so that no long item is left for one worker while the other is idle
    # (stable: the order within a module is kept)
    items.sort(key=lambda it: 0 if it.get_closest_marker("xdist_group") else
               1 if it.get_closest_marker("slow") else 2)


def _shares_a_fixture(item):
    """The test uses a fixture wider than one test, defined in its own module."""
    info = getattr(item, "_fixtureinfo", None)
    for defs in (info.name2fixturedefs.values() if info else ()):
        for d in defs:
            if d.scope in ("module", "session", "package") and \
                    getattr(d, "baseid", "").endswith(".py") and item.nodeid.startswith(d.baseid):
                return True
    return False


class _Spawns:
    """What the tests of this process start: every subprocess.Popen (subprocess.run, the
    firmware validation's builds and emulators, cffi's compiler) is classified as an
    emulator, a build or neither; pytest_runtest_setup starts a test's list, its teardown's
    report reads it (module and session fixtures count for the test that first uses them)."""
    EMULATORS = ("qemu-system-", "simavr")
    COMPILERS = {"gcc", "cc", "c++", "g++", "clang", "clang-14", "cmake", "make", "ar",
                 "arduino-builder"}
    CROSS = ("-gcc", "-g++", "-ld", "-ar", "-objcopy")

    def __init__(self):
        self.seen = []
        self.lock = threading.Lock()
        self._init = subprocess.Popen.__init__
        spawns = self

        def init(popen, args, *a, **kw):
            what = spawns.kind(args)
            if what:
                with spawns.lock:
                    spawns.seen.append(what)
            spawns._init(popen, args, *a, **kw)
        subprocess.Popen.__init__ = init

    @classmethod
    def kind(cls, args):
        """'emulator: <program>', 'build: <program>' or None for a Popen's args."""
        argv = [os.fsdecode(a) for a in ([args] if isinstance(args, (str, bytes, os.PathLike))
                                         else list(args))]
        if not argv:
            return None
        words = argv[0].split() if len(argv) == 1 else argv
        prog = os.path.basename(words[0])
        if prog.startswith(cls.EMULATORS[0]) or prog == cls.EMULATORS[1]:
            return f"emulator: {prog}"
        if prog in cls.COMPILERS or prog.endswith(cls.CROSS):
            return f"build: {prog}"
        if prog.startswith("python") or words[0] == sys.executable:
            rest = words[1:]
            if "setup.py" in rest:
                return "build: setup.py"
            if rest[:2] == ["-m", "imufuse"] and "validate" in rest:
                target = rest[rest.index("--target") + 1] if "--target" in rest[:-1] else "host"
                return f"{'build' if target == 'host' else 'emulator'}: imufuse validate"
        return None


_SPAWNS = _Spawns()


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    with _SPAWNS.lock:
        _SPAWNS.seen.clear()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    rep = outcome.get_result()
    if call.when != "teardown" or item.get_closest_marker("slow") is not None:
        return
    with _SPAWNS.lock:
        started = sorted(set(_SPAWNS.seen))
    if started and rep.outcome == "passed":
        rep.outcome = "failed"
        rep.longrepr = (f"{item.nodeid} is not marked slow but started {', '.join(started)}: "
                        "the inner loop (pytest -m 'not slow') runs no emulator or build; "
                        "mark its module in tests/conftest.py (EMULATOR, CROSSBUILD, FUZZ, SLOW) "
                        "or the test (SLOW_TESTS, EMULATOR_TESTS)")
