"""LLVM IR building blocks shared by the explicit-SIMD kernels (:mod:`simd_gather`, the remap
and warp pixel gathers; :mod:`simd_resize`, the uint8 RGB halving): vector types, shuffles,
splats and the numba type checks their intrinsics make.

Adding an intrinsic safely (docs/architecture.md, "Adding an intrinsic safely"):

- over-read span: a vector load reads a power-of-two number of bytes that may pass the last
  pixel it needs; the caller keeps every such read inside the array (see ``span``), and the
  tests run each kernel on images whose last row ends at the end of the allocation;
- cache: an ``@intrinsic`` is compiled into its caller, so its caller has ``cache=True`` and
  any Python-level choice it depends on (a CPU feature, a literal) is part of its typing
  (``prefer_literal``), never a global read at run time;
- target CPU: code for one instruction set (AVX2's ``vpmaddwd``) is chosen by the CPU numba
  compiles for (``NUMBA_CPU_NAME``/``NUMBA_CPU_FEATURES``, else the host), with a generic path
  every CPU runs.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types

__all__: list[str] = []

_I8, _I16, _I32, _I64, _F32 = ir.IntType(8), ir.IntType(16), ir.IntType(32), ir.IntType(64), ir.FloatType()
_V = ir.VectorType


def _mask(idx) -> ir.Constant:
    idx = list(idx)
    return ir.Constant(_V(_I32, len(idx)), [ir.Constant(_I32, k) for k in idx])


def _splat(builder: ir.IRBuilder, x: ir.Value, n: int) -> ir.Value:
    v = builder.insert_element(ir.Constant(_V(_F32, n), ir.Undefined), x, ir.Constant(_I32, 0))
    return builder.shuffle_vector(v, v, _mask([0] * n))


def _to_f32(builder: ir.IRBuilder, x: ir.Value) -> ir.Value:
    return x if x.type == _F32 else builder.fptrunc(x, _F32)


def _is_u8_vector(a) -> bool:
    return isinstance(a, types.Array) and a.dtype == types.uint8 and a.ndim == 1 and a.layout == "C"


def _is_weights(t) -> bool:
    return isinstance(t, types.UniTuple) and t.count in (2, 4, 6) and isinstance(t.dtype, types.Float)


def _is_weight_rows(a) -> bool:
    return isinstance(a, types.Array) and a.dtype == types.float32 and a.ndim == 2 and a.layout == "C"


def _is_f32_vector(a) -> bool:
    return isinstance(a, types.Array) and a.dtype == types.float32 and a.ndim == 1 and a.layout == "C"


def _is_u8_rows(a) -> bool:
    return isinstance(a, types.Array) and a.dtype == types.uint8 and a.ndim == 2 and a.layout == "C"
