"""Every public function declared in csrc/*.h and csrc/fixed/*.h carries a doc comment: the
comment that ends right above it, or above the block of declarations it belongs to (the IMU
and AHRS variants of one call share one), names its units, ranges or behaviour."""
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
HEADERS = (sorted((ROOT / "csrc").glob("*.h")) + sorted((ROOT / "csrc" / "fixed").glob("*.h"))
           + sorted((ROOT / "csrc" / "hil").glob("*.h")))
_DECL = re.compile(r"^(?:const\s+)?[A-Za-z_]\w*(?:\s+\w+)*\s+\**(imf_\w+)\s*\(")


def undocumented(text):
    lines = text.split("\n")
    out = []
    for i, line in enumerate(lines):
        m = _DECL.match(line)
        if not m or line.startswith(("static", "typedef", "#")):
            continue
        # a declaration (ends with ';' on this or a continuation line)
        j = i
        while j < len(lines) and ")" not in lines[j]:
            j += 1
        if j >= len(lines) or not lines[j].rstrip().endswith(";"):
            continue
        k = i - 1
        documented = False
        while k >= 0 and lines[k].strip():
            if lines[k].rstrip().endswith("*/") or "//" in lines[k]:
                documented = True
                break
            k -= 1
        if not documented:
            out.append(f"line {i + 1}: {m.group(1)}")
    return out


def test_headers_found():
    assert len(HEADERS) >= 20


@pytest.mark.parametrize("header", HEADERS, ids=[h.name for h in HEADERS])
def test_every_public_function_is_documented(header):
    assert not undocumented(header.read_text()), f"{header.name}: {undocumented(header.read_text())}"


def test_the_check_can_fail():
    assert undocumented("typedef int t;\n\nvoid imf_x_init(t *self, float dt);\n") == \
        ["line 3: imf_x_init"]
    assert undocumented("/* dt: s */\nvoid imf_x_init(t *self,\n    float dt);\n") == []


def undocumented_members(text):
    """Struct members in `text` with no comment on their line and no comment ending on the
    line right above."""
    out = []
    lines = text.split("\n")
    in_struct = in_comment = False
    above = False   # the previous line ended a comment
    for i, line in enumerate(lines):
        s = line.strip()
        if in_comment:
            in_comment = "*/" not in s
            above = not in_comment
            continue
        if re.match(r"(typedef\s+)?struct\b[^;]*\{\s*$", s):
            in_struct, above = True, False
            continue
        if not in_struct:
            continue
        if s.startswith("}"):
            in_struct = False
            continue
        code, _, comment = s.partition("/*")
        if code.strip().endswith(";") and not comment and "//" not in s and not above:
            out.append(f"line {i + 1}: {code.strip()}")
        if comment and "*/" not in comment:
            in_comment = True
        above = bool(comment) and not code.strip() and "*/" in comment
    return out


@pytest.mark.parametrize("header", HEADERS, ids=[h.name for h in HEADERS])
def test_every_struct_member_is_documented(header):
    """Every member of every struct in the public headers says what it holds (its unit,
    format or meaning), on its line or in a comment right above."""
    assert not undocumented_members(header.read_text()), \
        f"{header.name}: {undocumented_members(header.read_text())}"


def test_the_member_check_can_fail():
    text = ("typedef struct {\n    float a; /* s */\n    /* gain */\n    float b;\n"
            "    float c;\n    float d; /* a long\n       comment; with a semicolon */\n} t;\n")
    assert undocumented_members(text) == ["line 5: float c;"]


@pytest.mark.parametrize("src", sorted((ROOT / "csrc").glob("*.c"))
                         + sorted((ROOT / "csrc" / "fixed").glob("*.c")), ids=lambda p: p.name)
def test_which_files_names_every_header_a_source_includes(src):
    """docs/firmware.md's "Which files" tells an embedded user what to copy; robust.c's
    robust_b3.h was missing from it ("fatal error: robust_b3.h: No such file" on a copy of
    exactly the list). Each source's headers, as the preprocessor finds them (gcc -MM), are
    named there (or are its own pair's, or csrc/fixed/imf_fixed*.h)."""
    import os
    import subprocess
    text = (ROOT / "docs" / "firmware.md").read_text()
    section = text[text.index("### Which files"):text.index("Or copy all of `csrc/`")]
    out = subprocess.run(["gcc", "-std=c99", "-MM", f"-I{ROOT / 'csrc'}",
                          f"-I{ROOT / 'csrc' / 'fixed'}", str(src)],
                         capture_output=True, text=True, check=True).stdout
    headers = {os.path.basename(d) for d in out.replace("\\\n", " ").split()[1:]
               if d.endswith(".h")}
    missing = sorted(h for h in headers if Path(h).stem != src.stem and f"`{h}`" not in section
                     and not (h.startswith("imf_fixed") and "imf_fixed*.h" in section))
    assert not missing, f"{src.name} includes {missing}, which docs/firmware.md does not list"
