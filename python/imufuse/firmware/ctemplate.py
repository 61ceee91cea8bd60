"""The templates of a declared firmware API checked as C before anything is generated
(``scan``, ``value_type``), and the C library's system calls a declared firmware gets on an
emulated MCU (``BARE_METAL``): a heap inside the saved RAM image for malloc and new, output
that goes nowhere for printf (imufuse.firmware.declared)."""
from __future__ import annotations

import re
from typing import Any

from .declaration import FirmwareError

__all__ = ["scan", "value_type", "KEYWORDS", "BARE_METAL", "BARE_METAL_CXX"]

KEYWORDS = frozenset(
    "auto break case char const continue default do double else enum extern float for goto if "
    "inline int long register restrict return short signed sizeof static struct switch typedef "
    "union unsigned void volatile while bool class delete new namespace operator private "
    "protected public template this throw try catch typename using virtual asm main".split())
_LEAVE = ("return", "goto", "break", "continue", "asm", "__asm__", "__asm", "longjmp")
_NOT_A_TYPE = frozenset("static extern register typedef inline const volatile void auto".split())
# a class, struct or builtin type: words, '::' and template arguments; no pointer or array
TYPE = re.compile(r"(?:(?:struct|union|class|enum)\s+)?(?:::)?[A-Za-z_][\w\s:<>,.]*$")


def scan(text: str, where: str, kind: str) -> str:
    """A template checked as C (FirmwareError naming `where`): literals and comments closed,
    brackets balanced, no placeholder inside a literal, no '#' or stray backslash, nothing
    that leaves the harness's code; kind "expr" (a state expression): one expression without
    side effects; "args": no ';'. Returns it with its comments replaced by spaces."""
    def fail(msg: str) -> None:
        raise FirmwareError(f"{where}: {msg} (in {text.strip()[:80]!r})")
    if re.search(r"\?\?[=/'()!<>-]", text):
        fail("a trigraph (??=, ??/, ??<, ...) is not taken in a template")
    out, stack, bare, i, n = [], [], [], 0, len(text)
    while i < n:
        c, two = text[i], text[i:i + 2]
        if two in ("//", "/*"):
            j = text.find("\n" if two == "//" else "*/", i + 2)
            if j < 0 and two == "/*":
                fail("a comment /* without its */")
            out.append(" ")
            i = n if j < 0 else j + (0 if two == "//" else 2)
            continue
        if c in "\"'":
            word = re.search(r"\w*$", text[:i]).group()  # type: ignore[union-attr]
            if c == "'" and word and word not in ("L", "u", "U", "u8"):
                fail("a digit separator (') is not taken in a template")
            if c == '"' and word.endswith("R"):
                fail("a raw string literal is not taken in a template")
            j = i + 1
            while j < n and text[j] not in (c, "\n"):
                j += 2 if text[j] == "\\" else 1
            if j >= n or text[j] != c:
                fail(f"a literal without its closing {c}")
            if "${" in text[i:j]:
                fail("a placeholder inside a string or character literal is not replaced")
            out.append(text[i:j + 1])
            bare.append(" 0 ")
            i = j + 1
            continue
        if two == "$$" or two == "${":
            j = i + 1 if two == "$$" else text.find("}", i)
            if j < 0:
                fail("'${' without its closing '}'")
            if kind == "expr" and two == "${":
                fail("a state expression takes no placeholder")
            out.append(text[i:j + 1])
            bare.append(" 0 ")
            i = j + 1
            continue
        if two in ("<%", "%>", "%:", ":>") or (two == "<:" and text[i:i + 3] != "<::"):
            fail(f"a digraph ({two}) is not taken in a template: write the bracket itself")
        if c in "([{":
            stack.append(c)
        elif c in ")]}":
            if not stack or stack.pop() != "([{"[")]}".index(c)]:
                fail(f"unbalanced '{c}'")
        elif c == "#":
            fail("'#': a preprocessor directive belongs in the sources or [firmware] defines")
        elif c == "\\":
            fail("a backslash outside a literal")
        if kind != "stmt" and (c == ";" or (kind == "expr" and c in "{}")):
            fail("one expression: no ';' or braces")
        if kind == "expr" and c == "," and not stack:
            fail("one expression: no top-level comma")
        out.append(c)
        bare.append(c)
        i += 1
    if stack:
        fail(f"'{stack[-1]}' without its closing bracket")
    code = "".join(bare)
    for word in re.findall(r"[A-Za-z_]\w*", code):
        if word in _LEAVE:
            fail(f"'{word}' would leave the harness's code (put it in a function of the sources)")
    if kind == "expr":
        for op in re.findall(r"<<=|>>=|[=!<>]=|->|\+\+|--|[-+*/%&|^]?=", code):
            if op in ("++", "--") or (op.endswith("=") and op not in ("==", "!=", "<=", ">=")):
                fail(f"'{op}' changes the filter: a state expression only reads it")
    return "".join(out)


def value_type(t: Any, where: str) -> str:
    """A value type (float, double, int16_t, unsigned char) or FirmwareError."""
    if not isinstance(t, str) or not re.fullmatch(r"[A-Za-z_][\w ]*", t.strip()) \
            or _NOT_A_TYPE & set(t.split()):
        raise FirmwareError(f"{where}: {t!r}: a C value type (float, double, int16_t)")
    return t.strip()




# The C library's system calls on bare metal for a firmware that allocates (malloc, new) or
# prints (printf): weak (the firmware's own win), each in a section of its own (dropped when
# unused: no cost to a firmware that does neither). The Arm heap is an array in .bss, inside
# the RAM image the driver saves between chunks; printf's output goes nowhere (the
# emulator's output is the harness's). IMF_FW_HEAP (a [firmware] define) sets its size.
BARE_METAL = r"""
#if defined(__arm__)
#ifndef IMF_FW_HEAP
#if defined(__ARM_ARCH_6M__)
#define IMF_FW_HEAP 4096
#else
#define IMF_FW_HEAP 65536
#endif
#endif
static unsigned char imf_fw_heap[IMF_FW_HEAP]
    __attribute__((aligned(8), section(".bss.imf_fw_heap")));
static unsigned int imf_fw_brk __attribute__((section(".bss.imf_fw_brk")));
#define IMF_FW_WEAK(s) __attribute__((weak, section(".text.imf_fw_" #s)))
void *_sbrk(int incr) IMF_FW_WEAK(sbrk);
void *_sbrk(int incr)
{
    unsigned int old = imf_fw_brk;
    if (incr < 0 ? (unsigned int)-incr > old : (unsigned int)incr > IMF_FW_HEAP - old) {
        return (void *)-1;
    }
    imf_fw_brk = old + (unsigned int)incr;
    return imf_fw_heap + old;
}
int _write(int fd, const char *b, int n) IMF_FW_WEAK(write);
int _write(int fd, const char *b, int n) { (void)fd; (void)b; return n; }
int _read(int fd, char *b, int n) IMF_FW_WEAK(read);
int _read(int fd, char *b, int n) { (void)fd; (void)b; (void)n; return 0; }
int _close(int fd) IMF_FW_WEAK(close);
int _close(int fd) { (void)fd; return -1; }
int _lseek(int fd, int off, int whence) IMF_FW_WEAK(lseek);
int _lseek(int fd, int off, int whence) { (void)fd; (void)off; (void)whence; return 0; }
int _fstat(int fd, void *st) IMF_FW_WEAK(fstat);
int _fstat(int fd, void *st) { (void)fd; (void)st; return -1; }
int _isatty(int fd) IMF_FW_WEAK(isatty);
int _isatty(int fd) { (void)fd; return 1; }
int _kill(int pid, int sig) IMF_FW_WEAK(kill);
int _kill(int pid, int sig) { (void)pid; (void)sig; return -1; }
int _getpid(void) IMF_FW_WEAK(getpid);
int _getpid(void) { return 1; }
#endif
"""

# new and delete on the ATmega328P (avr-g++ has no C++ library): malloc and free, from a heap
# in .bss (inside the saved RAM image, away from the harness's stack guard) that the first
# new sets up while avr-libc's heap is untouched
BARE_METAL_CXX = r"""
#if defined(__AVR__)
#include <stdlib.h>
#ifndef IMF_FW_HEAP
#define IMF_FW_HEAP 256
#endif
extern "C" { extern char *__malloc_heap_start; extern char *__malloc_heap_end; extern char *__brkval; }
static char imf_fw_heap[IMF_FW_HEAP] __attribute__((section(".bss.imf_fw_heap")));
#define IMF_FW_WEAK(s) __attribute__((weak, section(".text.imf_fw_" #s)))
static void *imf_fw_alloc(size_t n) __attribute__((section(".text.imf_fw_alloc")));
static void *imf_fw_alloc(size_t n)
{
    if (__brkval == 0) {
        __malloc_heap_start = imf_fw_heap;
        __malloc_heap_end = imf_fw_heap + IMF_FW_HEAP;
    }
    return malloc(n);
}
void *operator new(size_t n) IMF_FW_WEAK(new);
void *operator new(size_t n) { return imf_fw_alloc(n); }
void *operator new[](size_t n) IMF_FW_WEAK(new_a);
void *operator new[](size_t n) { return imf_fw_alloc(n); }
void operator delete(void *p) IMF_FW_WEAK(delete);
void operator delete(void *p) { free(p); }
void operator delete[](void *p) IMF_FW_WEAK(delete_a);
void operator delete[](void *p) { free(p); }
void operator delete(void *p, size_t) IMF_FW_WEAK(delete_s);
void operator delete(void *p, size_t) { free(p); }
void operator delete[](void *p, size_t) IMF_FW_WEAK(delete_as);
void operator delete[](void *p, size_t) { free(p); }
extern "C" void __cxa_pure_virtual(void) IMF_FW_WEAK(pure);
extern "C" void __cxa_pure_virtual(void) { abort(); }
#endif
"""
