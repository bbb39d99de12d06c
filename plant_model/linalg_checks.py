"""Input checks shared by every component: shapes, finiteness, symmetry, definiteness.

Each check raises :class:`ModelError` with a message that names the matrix and the
problem, so that a scenario loader, a CLI and an FMU slave can all report it as is.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = [
    "ModelError",
    "fmt_complex",
    "as_float",
    "as_matrix",
    "as_square",
    "readonly",
    "as_nonnegative",
    "as_number",
    "as_positive",
    "as_vector",
    "first_non_number",
    "not_a_number",
    "refuse_text",
    "check_symmetric_psd",
    "check_symmetric_pd",
    "uncontrollable_modes",
    "unobservable_modes",
]


class ModelError(ValueError):
    """A model, design or scenario is invalid; the message names what is wrong."""


def as_matrix(name: str, value: Any, shape: Sequence[int | None] | None = None) -> np.ndarray:
    """Return ``value`` as a finite 2-D float array, checking its shape.

    ``shape`` entries may be ``None`` for "any size". A 1-D value is one row.

    Parameters
    ----------
    name : str
        The matrix's name in error messages.
    value : Any
        Nested lists or an array.
    shape : Sequence[int or None] or None, optional
        Expected (rows, columns); None: any shape.

    Returns
    -------
    np.ndarray
        A float copy, 2-D.

    Raises
    ------
    ModelError
        If ``value`` is not numeric, not 2-D, of the wrong shape or not finite.
    """
    refuse_text(name, value, "matrix")
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ModelError(f"{name}: not a numeric matrix ({exc})") from None
    if arr.ndim == 0:
        raise ModelError(f"{name}: expected a matrix, got the scalar {arr.item()!r}")
    if arr.ndim == 1:
        arr = arr.reshape(1, -1)
    if arr.ndim != 2:
        raise ModelError(f"{name}: expected a 2-D matrix, got an array with {arr.ndim} dimensions")
    if shape is not None:
        for got, want in zip(arr.shape, shape):
            if want is not None and got != want:
                exp = "x".join("?" if s is None else str(s) for s in shape)
                raise ModelError(
                    f"{name}: wrong shape {arr.shape[0]}x{arr.shape[1]}, expected {exp}"
                )
    _check_finite(name, arr)
    return arr


def as_square(name: str, value: Any) -> np.ndarray:
    """Return ``value`` as a finite square 2-D float array: :func:`as_matrix` with as many
    columns as rows (the same ModelError otherwise)."""
    arr = as_matrix(name, value)
    return as_matrix(name, arr, (arr.shape[0], arr.shape[0]))


def readonly(a: Any) -> np.ndarray:
    """A read-only float copy of ``a`` (the arrays of a frozen model)."""
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


def as_vector(name: str, value: Any, length: int | None = None) -> np.ndarray:
    """Return ``value`` as a finite 1-D float array of the given length.

    As :func:`as_matrix` for a vector: ``value`` a list, an array or a scalar (a vector of
    length 1), ``length`` the expected length (None: any); returns a 1-D float copy; raises
    ModelError if ``value`` is not numeric, not 1-D, of the wrong length or not finite.
    """
    refuse_text(name, value, "vector")
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ModelError(f"{name}: not a numeric vector ({exc})") from None
    arr = np.atleast_1d(arr)
    if arr.ndim != 1:
        raise ModelError(f"{name}: expected a vector, got an array of shape {arr.shape}")
    if length is not None and arr.shape[0] != length:
        raise ModelError(f"{name}: wrong length {arr.shape[0]}, expected {length}")
    _check_finite(name, arr)
    return arr


def first_non_number(value: Any) -> Any | None:
    """The first string or boolean in ``value`` (nested lists, an array), or None: numpy
    would read "2" as 2.0 and true as 1.0. Arrays of numbers pass without a scan."""
    if isinstance(value, np.ndarray) and value.dtype.kind in "fiuc":
        return None
    stack = [value]                                  # first entry first: reversed pushes
    while stack:
        item = stack.pop()
        if isinstance(item, (str, bytes, bool, np.bool_)):
            return item
        if isinstance(item, (list, tuple)):
            stack.extend(reversed(item))
        elif isinstance(item, np.ndarray) and item.dtype.kind not in "fiuc":
            stack.extend(reversed(item.tolist()))
    return None


def not_a_number(item: Any) -> str:
    """``'2' is text, not a number (write numbers without quotes)`` for an entry of
    :func:`first_non_number`."""
    kind = "a boolean" if isinstance(item, (bool, np.bool_)) else "text"
    hint = " (write numbers without quotes)" if _quoted(item) else ""
    return f"{item!r} is {kind}, not a number{hint}"


def refuse_text(name: str, value: Any, what: str = "matrix") -> None:
    """Refuse a string or a boolean anywhere in ``value`` (:func:`first_non_number`): a TOML
    matrix holds numbers."""
    item = first_non_number(value)
    if item is not None:
        raise ModelError(f"{name}: not a numeric {what}: {not_a_number(item)}")


def _quoted(value: Any) -> str:
    """A hint for a string that spells a number: TOML numbers have no quotes."""
    try:
        float(value)
    except (TypeError, ValueError):
        return ""
    return " (text: write numbers without quotes)" if isinstance(value, (str, bytes)) else ""


def _check_finite(name: str, arr: np.ndarray) -> None:
    bad = np.argwhere(~np.isfinite(arr))
    if bad.size:
        idx = tuple(int(i) + 1 for i in bad[0])
        where = f"[{','.join(map(str, idx))}]"
        raise ModelError(f"{name}{where} = {arr[tuple(bad[0])]} is not finite")


def check_symmetric_psd(name: str, M: np.ndarray, *, definite: bool = False) -> None:
    """Require ``M`` symmetric and positive semidefinite (definite if asked).

    Symmetry tolerance: ``|M - M'| <= 1e-10 (1 + max|M|)``; eigenvalue tolerance
    ``1e-12 (1 + max|M|)``.

    Parameters
    ----------
    name : str
        The matrix's name in error messages.
    M : np.ndarray
        Square matrix.
    definite : bool, optional
        Require positive definite instead of semidefinite.

    Raises
    ------
    ModelError
        If ``M`` is not symmetric, or its smallest eigenvalue is negative (not positive
        when ``definite``).
    """
    scale = 1.0 + float(np.max(np.abs(M))) if M.size else 1.0
    asym = float(np.max(np.abs(M - M.T))) if M.size else 0.0
    if asym > 1e-10 * scale:
        i, j = np.unravel_index(int(np.argmax(np.abs(M - M.T))), M.shape)
        raise ModelError(
            f"{name} is not symmetric: {name}[{i + 1},{j + 1}] = {M[i, j]:g} but "
            f"{name}[{j + 1},{i + 1}] = {M[j, i]:g}"
        )
    if not M.size:
        return
    eig = np.linalg.eigvalsh(0.5 * (M + M.T))
    tol = 1e-12 * scale
    lo = float(eig.min())
    if definite and lo <= tol:
        raise ModelError(
            f"{name} must be positive definite; its smallest eigenvalue is {lo:.6g}"
        )
    if lo < -tol:
        raise ModelError(
            f"{name} must be positive semidefinite (a covariance or intensity); "
            f"its smallest eigenvalue is {lo:.6g}"
        )


def check_symmetric_pd(name: str, M: np.ndarray) -> None:
    """Require ``M`` symmetric positive definite: :func:`check_symmetric_psd` with
    ``definite=True`` (its parameters; ModelError if ``M`` is not symmetric or not positive
    definite).
    """
    check_symmetric_psd(name, M, definite=True)


def _pbh_rank_deficient(A: np.ndarray, X: np.ndarray, lam: complex, *, rows: bool) -> bool:
    n = A.shape[0]
    Ml = A - lam * np.eye(n)
    M = np.hstack([Ml, X]) if rows else np.vstack([Ml, X])
    s = np.linalg.svd(M, compute_uv=False)
    scale = max(1.0, float(np.linalg.norm(A, 2)), float(np.linalg.norm(X, 2)) if X.size else 0.0)
    return s[-1] <= 1e-9 * scale if s.size >= n else True


def uncontrollable_modes(A: np.ndarray, B: np.ndarray, *, only_unstable: bool = True,
                         continuous: bool = True) -> list[complex]:
    """Eigenvalues lambda of A where rank [A - lambda I, B] < n (PBH test).

    Parameters
    ----------
    A : np.ndarray
        State matrix, n x n.
    B : np.ndarray
        Input matrix, n x m.
    only_unstable : bool, optional
        Report only the modes that are not asymptotically stable.
    continuous : bool, optional
        Stability in continuous time (Re lambda < 0) rather than discrete (|lambda| < 1).

    Returns
    -------
    list[complex]
        The uncontrollable (unstable) eigenvalues.
    """
    out = []
    for lam in np.linalg.eigvals(A):
        unstable = lam.real >= -1e-9 if continuous else abs(lam) >= 1 - 1e-9
        if only_unstable and not unstable:
            continue
        if _pbh_rank_deficient(A, B, lam, rows=True):
            out.append(complex(lam))
    return out


def unobservable_modes(A: np.ndarray, C: np.ndarray, *, only_unstable: bool = True,
                       continuous: bool = True) -> list[complex]:
    """Eigenvalues lambda of A where rank [A - lambda I; C] < n (PBH test).

    Parameters as :func:`uncontrollable_modes`, with the output matrix C (p x n) in place
    of B; returns the unobservable (unstable) eigenvalues, the uncontrollable ones of
    (A', C').
    """
    return uncontrollable_modes(A.T, C.T, only_unstable=only_unstable, continuous=continuous)


def as_number(name: str, value: Any) -> float:
    """A finite float, or a :class:`ModelError` naming ``name``.

    Parameters
    ----------
    name : str
        The quantity's name in error messages.
    value : Any
        A number (booleans are refused).

    Returns
    -------
    float
        ``float(value)``.

    Raises
    ------
    ModelError
        If ``value`` is a boolean, not a number or not finite.
    """
    if isinstance(value, bool):
        raise ModelError(f"{name}: expected a number, got {value!r}")
    return as_float(name, value)


def as_float(name: str, value: Any) -> float:
    """``float(value)``, finite (a boolean counts as 0 or 1: see :func:`as_number`); a
    string is refused even when it spells a number (a TOML number has no quotes).

    Raises
    ------
    ModelError
        If ``value`` is not a number or not finite.
    """
    if isinstance(value, (str, bytes)):         # "1525" is text, not a number: say so
        raise ModelError(f"{name}: not a number: {value!r}" + _quoted(value))
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ModelError(f"{name}: not a number: {value!r}") from None
    if not math.isfinite(x):
        raise ModelError(f"{name} = {x} is not finite")
    return x


def as_positive(name: str, value: Any, unit: str) -> float:
    """A finite float > 0 (``unit`` only for the message).

    Parameters
    ----------
    name : str
        The quantity's name in error messages.
    value : Any
        A number.
    unit : str
        Its unit, for the message.

    Returns
    -------
    float
        The number, checked by :func:`as_number` (booleans are refused).

    Raises
    ------
    ModelError
        If ``value`` is not a finite number or not positive.
    """
    x = as_number(name, value)
    if x <= 0.0:
        raise ModelError(f"{name} = {x:g} {unit} must be positive")
    return x


def as_nonnegative(name: str, value: Any, unit: str) -> float:
    """A finite float >= 0 (``unit`` only for the message).

    Parameters and returns as :func:`as_positive`; raises ModelError if ``value`` is not a
    finite number or is negative.
    """
    x = as_number(name, value)
    if x < 0.0:
        raise ModelError(f"{name} = {x:g} {unit} must not be negative")
    return x


def fmt_complex(z: complex) -> str:
    """An eigenvalue as the error messages print it: ``0.5`` when real (imaginary part under
    1e-12), else ``0.5+0.25j``; 6 significant digits."""
    z = complex(z)
    return f"{z.real:.6g}" if abs(z.imag) < 1e-12 else f"{z.real:.6g}{z.imag:+.6g}j"
