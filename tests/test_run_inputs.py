"""run() reads C-contiguous float32/float64 arrays in place and converts the
other float type element by element in C: every input layout and type gives
the state trajectory of the same values rounded to the filter's precision,
bit for bit."""
import numpy as np
import pytest

from bits import assert_same_bits
from imufuse.registry import (FLOAT_CASES, case_params, each_dtype, float_matrix)
from sequences import generate

OTHER = {"float32": np.float64, "float64": np.float32}


def layouts(arrays, dtype):
    """The same values in every layout run() accepts."""
    same = [np.ascontiguousarray(a, dtype=dtype) for a in arrays]
    yield "other float type", [a.astype(OTHER[dtype]) for a in same]
    yield "strided view", [np.repeat(a, 2, axis=0)[::2] for a in same]
    yield "fortran order", [np.asfortranarray(a) for a in same]
    yield "big endian", [a.astype(a.dtype.newbyteorder(">")) for a in same]
    yield "lists", [a.tolist() for a in same]
    yield "int", [(a * 4).astype(np.int64) for a in same]
    yield "mixed", [same[0].astype(OTHER[dtype]), *same[1:]]


@pytest.mark.parametrize("case", case_params(FLOAT_CASES))
@each_dtype
def test_every_input_layout_gives_the_same_bits(case, dtype):
    arrays = [np.asarray(a) for a in generate(case.kind, "random")]
    if dtype == "float64":     # values a float32 array can hold, so every layout is exact
        arrays = [a.astype(np.float32).astype(np.float64) for a in arrays]
    for label, inputs in layouts(arrays, dtype):
        want_in = [np.ascontiguousarray(np.asarray(x, dtype=np.float64), dtype=dtype)
                   for x in inputs]
        want = case.make("c", dtype).run(*want_in)
        got = case.make("c", dtype).run(*inputs)
        assert got.dtype == np.dtype(dtype) and got.flags.c_contiguous
        assert_same_bits(got, want, case.make("c", dtype).state_names), label
    # the reference agrees on the converting path too
    other = [np.ascontiguousarray(a, dtype=dtype).astype(OTHER[dtype]) for a in arrays]
    assert_same_bits(case.make("c", dtype).run(*other), case.make("ref", dtype).run(*other))


@pytest.mark.parametrize("case,dtype", float_matrix()[:1] + float_matrix()[-1:])
def test_mismatched_inputs_still_raise(case, dtype):
    arrays = [np.asarray(a, dtype=dtype) for a in generate(case.kind, "random")]
    with pytest.raises(ValueError, match="shapes"):
        case.make("c", dtype).run(arrays[0][:-1], *arrays[1:])
    with pytest.raises(ValueError, match="shapes"):
        case.make("c", dtype).run(arrays[0][..., None], *arrays[1:])
