"""The small C++ filter class the declared-API tests share (tests/test_firmware_declared.py,
test_declared_hostile.py, test_firmware_versus.py): Eq. 2.5's Kalman1D step as a class with
private state, initialised by a method, and its declaration; `write(dir, ...)` puts the three
files in a directory, with any of them changed, and returns the declaration's path."""
import textwrap

H = textwrap.dedent("""
    class Attitude {
    public:
        void begin(float k0) { k0_ = k0; omk0_ = 1.0f - k0; theta_ = 0.0f; }
        void step(float gyro, float acc_angle, float dt);
    private:
        float theta_, k0_, omk0_;
    };
""")
CPP = textwrap.dedent("""
    #include "att.hpp"
    void Attitude::step(float gyro, float acc_angle, float dt)
    {
        if (!__builtin_isfinite(gyro) || !__builtin_isfinite(acc_angle)) return;
        float pred = theta_ + gyro * dt;
        float th = omk0_ * pred + k0_ * acc_angle;
        if (__builtin_isfinite(th)) theta_ = th;
    }
""")
TOML = textwrap.dedent("""
    [firmware]
    sources = ["att.cpp"]
    headers = ["att.hpp"]

    [filter]
    name = "Kalman1D"
    params = { k0 = 0.02 }

    [object]
    type = "Attitude"
    init = ["fw.begin(${k0})"]

    [update]
    call = "fw.step(${rate}, ${angle}, ${dt})"

    [state]
    theta = "fw.theta_"
""")


def write(d, toml=TOML, h=H, cpp=CPP, edits=()):
    """att.hpp, att.cpp and att.toml in directory d (made if missing), the declaration with
    `edits` (old, new) applied (each old must be there); returns att.toml's path."""
    d.mkdir(parents=True, exist_ok=True)
    for old, new in edits:
        assert old in toml, old
        toml = toml.replace(old, new)
    (d / "att.hpp").write_text(h)
    (d / "att.cpp").write_text(cpp)
    p = d / "att.toml"
    p.write_bytes(toml if isinstance(toml, bytes) else toml.encode())
    return p
