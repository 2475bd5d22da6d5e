"""Sums of products in a fixed order, so that geometry comes out bit for bit on every machine.

numpy's `@`, np.dot and friends hand float64 products to OpenBLAS, which picks its kernels by
the CPU it runs on (Haswell, SkylakeX, ...), and each adds in its own order: the same scene's
transformed points, Bezier nets of NURBS surfaces and trim curves then differ in their last
bits from machine to machine (seen: the channel digests of transformed and NURBS scenes moved
on an AVX-512 machine, and matched again with OPENBLAS_CORETYPE=Haswell). Everything that
reaches the kernels is computed here instead: elementwise products added term by term, first
to last, which numpy rounds the same everywhere.
"""
from __future__ import annotations

import numpy as np


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a @ b for a (..., n) and b (n, ...): sum over k of a[..., k] * b[k], k = 0 first."""
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    lead, tail = a.shape[:-1], b.shape[1:]
    a2 = a.reshape(lead + (1,) * len(tail) + (a.shape[-1],))
    out = a2[..., 0] * b[0]
    for k in range(1, a.shape[-1]):
        out = out + a2[..., k] * b[k]
    return out


def dot3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row by row dot products of (..., 3) arrays, (a0 b0 + a1 b1) + a2 b2: np.sum(a * b, axis=-1)
    without a reduction per row (as slow as its rows are many)."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def affine(points: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """points (..., 3) through the 3 x 4 (or 4 x 4) affine matrix: L p + t, term by term."""
    m = np.asarray(matrix, np.float64)
    p = np.asarray(points, np.float64)
    return p[..., 0:1] * m[:3, 0] + p[..., 1:2] * m[:3, 1] + p[..., 2:3] * m[:3, 2] + m[:3, 3]


def matmul4(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a @ b of two 4 x 4 matrices."""
    return dot(np.asarray(a, np.float64), np.asarray(b, np.float64))


def sandwich(left: np.ndarray, net: np.ndarray, right: np.ndarray) -> np.ndarray:
    """einsum('aj,jic,bi->abc', left, net, right): a control net refined on both sides."""
    rows = dot(left, net)                                   # (a, i, c)
    return dot(right, np.moveaxis(rows, 1, 0)).transpose(1, 0, 2)  # (b, a, c) -> (a, b, c)


def norm(v: np.ndarray) -> float:
    """The length of one vector (np.linalg.norm of a vector is a BLAS dot)."""
    return float(np.sqrt(dot(v, v)))
