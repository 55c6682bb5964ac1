"""The C callbacks of the native SUNDIALS path: numba ``cfunc`` right-hand side, residual, Jacobians and roots.

SUNDIALS calls these through C function pointers with a ``void *user_data``; here
that is the address of an int64 array (the *user data*, slots ``UD_*`` below) that
holds the addresses of everything a callback reads: the parameter vector, the
mode, the guards of the mode and how many there are, the sections, scratch
arrays, and the two SUNDIALS accessors the callbacks need
(``N_VGetArrayPointer``, ``SUNDenseMatrix_Data``). The compiled event loop points
the slots at the run's own arrays (the mode and guards it updates at each
transition), so a callback reads the current mode without any Python.

The formulas are the per-arc adapters' (:mod:`nsbench.integrators._sundials_kernels`,
on the friction family's law), so the native and the per-arc paths integrate the
same systems: the right-hand sides, residuals and Jacobians are those functions
compiled again (:func:`_without_nrt`), the root functions compute each guard with
the same operations, written straight into their slots:

- CVODE: ``cvode_rhs``/``cvode_jacobian`` on ``[x1, v1, ..., c, s]`` (``c = cos(w t)``,
  ``s = sin(w t)`` as states for a forced problem; ``p`` with ``F = 0``);
- IDA: ``ida_residual``/``ida_jacobian`` on ``[x1, v1, ..., f1, ...]``.

Roots come in fixed slots: the first ``UD_SLOTS`` are guards (the mode's ``ng``
guards, then ``1.0`` in the slots the mode does not use, which never has a zero),
then one per section. So one solver serves every mode, with one direction vector.
The dense SUNDIALS matrix is column-major: it is viewed as a Fortran-ordered array.
"""

from __future__ import annotations

import types as pytypes
from typing import Any

import numba
import numpy as np
from numba import types

from nsbench.integrators import _sundials_kernels as sk
from nsbench.integrators._sundials_capi import address_of, c_function, f64_fmatrix, f64_matrix, f64_view, i64_view
from nsbench.model.compile import hot
from nsbench.model.records import linear_section_value
from nsbench.problems import friction_law as k

#: Views on memory SUNDIALS or nsbench owns, built where they are used: inlined into the callbacks (which are
#: compiled without reference counting; such a function may not return an array it did not receive).
view = numba.njit(cache=True, inline="always")

# ---------------------------------------------------------------------- the user data's slots
UD_NVGET = 0  # address of N_VGetArrayPointer
UD_MATDATA = 1  # address of SUNDenseMatrix_Data
UD_P = 2  # address of the parameter vector (CVODE: with F = 0), and its length
UD_NP = 3
UD_MODE = 4  # address of the mode (int64, n_blocks)
UD_NB = 5
UD_GK = 6  # addresses of the mode's guards: kinds, 0-based blocks, expected signs (int64)
UD_GI = 7
UD_GS = 8
UD_NG = 9  # the number of guards of the mode (a value)
UD_SLOTS = 10  # guard slots of the root function (a value: the most guards of any mode)
UD_NSEC = 11  # sections: their number, and addresses of their coefficients (n_sec x n) and levels
UD_SEC_C = 12
UD_SEC_L = 13
UD_N = 14  # mechanical states
UD_NEQ = 15  # the solver's equations
UD_FW = 16  # address of [F, w] (float64)
UD_SCRATCH = 17  # address of an n x n float64 scratch (IDA's Jacobian)
UD_SLIP = 18  # address of an int64 array of -1 per block (IDA's Jacobian)
UD_SIZE = 19

_nvget = c_function("p(p)")  # N_VGetArrayPointer(N_Vector) -> sunrealtype*


def _without_nrt(dispatcher):
    """The per-arc adapters' compiled function ``dispatcher`` compiled again without numba's reference
    counting (:func:`nsbench.model.compile.hot`: the same source, so the same formula; its updates cost
    several times the arithmetic of these small functions: 2-DOF ``cvode_rhs`` 123 ns with them), cached
    on disk under its own name (``<name>_hot``) beside the original."""
    f = dispatcher.py_func
    g = pytypes.FunctionType(f.__code__, f.__globals__, f.__name__ + "_hot", f.__defaults__, f.__closure__)
    g.__qualname__ = f.__qualname__ + "_hot"
    g.__module__, g.__doc__ = f.__module__, f.__doc__
    return hot(g)


cvode_rhs = _without_nrt(sk.cvode_rhs)
cvode_jacobian = _without_nrt(sk.cvode_jacobian)
ida_residual = _without_nrt(sk.ida_residual)
ida_jacobian = _without_nrt(sk.ida_jacobian)


@view
def _nv(ud, vector):
    """A view of an N_Vector's data (``UD_NEQ`` doubles)."""
    return f64_view(_nvget(ud[UD_NVGET], (address_of(vector),)), (ud[UD_NEQ],))


@view
def _ud(user_data):
    return i64_view(address_of(user_data), (UD_SIZE,))


@view
def _f1(address, size):
    return f64_view(address, (size,))


@view
def _i1(address, size):
    return i64_view(address, (size,))


@view
def _params(ud):
    return _f1(ud[UD_P], ud[UD_NP]), _i1(ud[UD_MODE], ud[UD_NB])


@view
def _sections(ud):
    n_sec, n = ud[UD_NSEC], ud[UD_N]
    coeffs = f64_matrix(ud[UD_SEC_C], (n_sec, n))
    return coeffs, _f1(ud[UD_SEC_L], n_sec)


@view
def _guards(ud):
    ng = ud[UD_NG]
    return _i1(ud[UD_GK], ng), _i1(ud[UD_GI], ng), _i1(ud[UD_GS], ng)


@hot
def _section_slots(ud, y, out):
    """The sections' values at ``y`` into the slots after the guards'."""
    n_sec = ud[UD_NSEC]
    if n_sec == 0:
        return
    coeffs, levels = _sections(ud)
    slots, n = ud[UD_SLOTS], ud[UD_N]
    for j in range(n_sec):
        out[slots + j] = linear_section_value(coeffs[j], levels[j], y[:n])


@hot
def cvode_root_values(ud, y, out, sections):
    """The root functions of the CVODE formulation at ``y`` into ``out``: ``expected_sign * guard`` in the
    guards' slots (``1.0`` in the slots the mode does not use), then, if ``sections``, the sections' values.

    Each value is computed as :func:`nsbench.integrators._sundials_kernels.cvode_roots` computes it (the same
    operations in the same order: tests/integrators/test_sundials_native.py), written in place."""
    p, mode = _params(ud)
    gk, gi, gs = _guards(ud)
    F = _f1(ud[UD_FW], 2)[0]
    ng, slots, nb, n = ud[UD_NG], ud[UD_SLOTS], ud[UD_NB], ud[UD_N]
    for q in range(ng):
        g = k.guard_value(p, mode, gk[q], gi[q], 0.0, y)
        if gk[q] != k.VELOCITY and gi[q] == nb - 1 and F != 0.0:
            g -= F * y[n]
        out[q] = gs[q] * g
    for q in range(ng, slots):
        out[q] = 1.0
    if sections:
        _section_slots(ud, y, out)


@hot
def ida_root_values(ud, y, out, sections):
    """The root functions of the IDA formulation at ``y`` (as
    :func:`nsbench.integrators._sundials_kernels.ida_roots`), in the slots of :func:`cvode_root_values`."""
    p, _ = _params(ud)
    gk, gi, gs = _guards(ud)
    ng, slots, n = ud[UD_NG], ud[UD_SLOTS], ud[UD_N]
    v0 = k.v0_of(p)
    for q in range(ng):
        i = gi[q]
        if gk[q] == k.VELOCITY:
            g = y[2 * i + 1] - v0
        elif gk[q] == k.UPPER:
            g = y[n + i] - k.block(p, k.FR, i)
        else:
            g = y[n + i] + k.block(p, k.FR, i)
        out[q] = gs[q] * g
    for q in range(ng, slots):
        out[q] = 1.0
    if sections:
        _section_slots(ud, y, out)


# ---------------------------------------------------------------------- the C signatures (cvode.h, ida.h, *_ls.h)
_I, _D, _P = types.int32, types.float64, types.voidptr
CV_RHS = _I(_D, _P, _P, _P)  # CVRhsFn(t, y, ydot, user_data)
CV_JAC = _I(_D, _P, _P, _P, _P, _P, _P, _P)  # CVLsJacFn(t, y, fy, Jac, user_data, tmp1, tmp2, tmp3)
CV_ROOT = _I(_D, _P, types.CPointer(_D), _P)  # CVRootFn(t, y, gout, user_data)
IDA_RES = _I(_D, _P, _P, _P, _P)  # IDAResFn(t, yy, yp, rr, user_data)
IDA_JAC = _I(_D, _D, _P, _P, _P, _P, _P, _P, _P, _P)  # IDALsJacFn(t, cj, yy, yp, rr, Jac, user_data, tmp1..3)
IDA_ROOT = _I(_D, _P, _P, types.CPointer(_D), _P)  # IDARootFn(t, yy, yp, gout, user_data)


def _callback(signature: Any) -> Any:
    """A C callback: numba ``cfunc`` for ``signature``, cached on disk, without reference counting."""
    options: dict[str, Any] = {"nopython": True, "cache": True, "_nrt": False}
    return numba.cfunc(signature, **options)


_matdata = c_function("p(p)")  # SUNDenseMatrix_Data(SUNMatrix) -> sunrealtype* (column-major)


@_callback(CV_RHS)
def cvode_rhs_c(t, y, ydot, user_data):
    ud = _ud(user_data)
    p, mode = _params(ud)
    fw = _f1(ud[UD_FW], 2)
    cvode_rhs(p, mode, fw[0], fw[1], _nv(ud, y), _nv(ud, ydot))
    return 0


@_callback(CV_JAC)
def cvode_jac_c(t, y, fy, jac, user_data, tmp1, tmp2, tmp3):
    ud = _ud(user_data)
    p, mode = _params(ud)
    fw = _f1(ud[UD_FW], 2)
    neq = ud[UD_NEQ]
    out = f64_fmatrix(_matdata(ud[UD_MATDATA], (address_of(jac),)), (neq, neq))
    cvode_jacobian(p, mode, fw[0], fw[1], _nv(ud, y), out)
    return 0


@_callback(CV_ROOT)
def cvode_root_c(t, y, gout, user_data):
    ud = _ud(user_data)
    cvode_root_values(ud, _nv(ud, y), f64_view(address_of(gout), (ud[UD_SLOTS] + ud[UD_NSEC],)), True)
    return 0


@_callback(IDA_RES)
def ida_res_c(t, yy, yp, rr, user_data):
    ud = _ud(user_data)
    p, mode = _params(ud)
    ida_residual(p, mode, t, _nv(ud, yy), _nv(ud, yp), _nv(ud, rr))
    return 0


@_callback(IDA_JAC)
def ida_jac_c(t, cj, yy, yp, rr, jac, user_data, tmp1, tmp2, tmp3):
    ud = _ud(user_data)
    p, mode = _params(ud)
    n, neq = ud[UD_N], ud[UD_NEQ]
    scratch = f64_matrix(ud[UD_SCRATCH], (n, n))
    slip_all = _i1(ud[UD_SLIP], ud[UD_NB])
    out = f64_fmatrix(_matdata(ud[UD_MATDATA], (address_of(jac),)), (neq, neq))
    ida_jacobian(p, mode, slip_all, t, _nv(ud, yy), cj, scratch, out)
    return 0


@_callback(IDA_ROOT)
def ida_root_c(t, yy, yp, gout, user_data):
    ud = _ud(user_data)
    ida_root_values(ud, _nv(ud, yy), f64_view(address_of(gout), (ud[UD_SLOTS] + ud[UD_NSEC],)), True)
    return 0


def addresses() -> dict[str, int]:
    """The C addresses of the callbacks (compiled, or loaded from numba's cache, on first use)."""
    return {
        "cvode_rhs": int(cvode_rhs_c.address),
        "cvode_jac": int(cvode_jac_c.address),
        "cvode_root": int(cvode_root_c.address),
        "ida_res": int(ida_res_c.address),
        "ida_jac": int(ida_jac_c.address),
        "ida_root": int(ida_root_c.address),
    }


def user_data() -> np.ndarray:
    """A zeroed user-data array."""
    return np.zeros(UD_SIZE, np.int64)
