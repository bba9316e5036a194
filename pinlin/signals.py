"""Input signals with a closed form, for :func:`pinlin.response`: steps, impulses, sinusoids.

A signal is a sum of parts, each acting on named inputs::

    u = pinlin.step({"u:shoulder": 2.0}) + pinlin.harmonic({"u:elbow": 0.5}, w=3.0)

- ``step(amplitude)``: u(t) = amplitude from the first sample time t[0] on [N*m or N].
- ``harmonic(amplitude, w, phase=0)``: u(t) = amplitude * sin(w t + phase), t the absolute time
  [s], w [rad/s], phase [rad].
- ``impulse(amplitude)``: a Dirac impulse of area ``amplitude`` [N*m*s or N*s] at t[0]; the
  response's first sample is the state just after it, x(t0+) = x0 + B amplitude.

Amplitudes name the inputs: a mapping {name: value} (a model input name such as
``"u:shoulder"``, or the name without its ``u:`` prefix; inputs not named get 0), an array of
one value per input (the model's input order), or a number for a single-input model.

Internally each part becomes complex exponentials: u(t) = sum_j c_j exp(mu_j (t - t0)) (a
step mu = 0; a sinusoid the conjugate pair mu = +-i w), which both response methods integrate
exactly (no sampling of the input).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .arrays import real_array
from .exceptions import ArgumentError

Amplitude = Mapping[str, float] | Sequence[float] | np.ndarray | float


@dataclass(frozen=True)
class _Part:
    kind: str          # "step" | "harmonic" | "impulse"
    amplitude: Any
    w: float = 0.0     # [rad/s]
    phase: float = 0.0  # [rad]


@dataclass(frozen=True)
class Signal:
    """A sum of steps, sinusoids and impulses on a model's inputs (add signals with ``+``).

    Attributes:
        parts: The terms, in the order they were added.
    """

    parts: tuple[_Part, ...]

    def __add__(self, other: object) -> Signal:
        if not isinstance(other, Signal):
            return NotImplemented
        return Signal(self.parts + other.parts)

    def resolve(self, input_names: Sequence[str], t0: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(impulse, c, mu): the impulse area per input (m), the coefficients c (m x J,
        complex) and exponents mu (J, [1/s]) of u(t) = sum_j c_j exp(mu_j (t - t0)).

        Raises:
            ArgumentError: an amplitude names an unknown input, or has the wrong size.
        """
        m = len(input_names)
        impulse = np.zeros(m)
        coef: list[np.ndarray] = []
        mu: list[complex] = []
        for part in self.parts:
            a = _amplitude(part.amplitude, input_names, part.kind)
            if part.kind == "impulse":
                with np.errstate(over="ignore"):
                    impulse += a
            elif part.kind == "step":
                coef.append(a.astype(complex))
                mu.append(0.0)
            else:  # a sin(w t + phase) = a (e^{i(w t + phase)} - e^{-i(w t + phase)}) / 2i
                z = np.exp(1j * (part.w * t0 + part.phase)) / 2j
                coef += [a * z, a * np.conj(z)]
                mu += [1j * part.w, -1j * part.w]
        c = np.array(coef).T if coef else np.zeros((m, 0), dtype=complex)
        with np.errstate(over="ignore", invalid="ignore"):
            total = np.abs(impulse) + np.abs(c).sum(axis=1)
        if not np.all(np.isfinite(total)):
            name = input_names[int(np.argmin(np.isfinite(total)))]
            raise ArgumentError("u", f"the amplitudes on input {name!r} add up beyond "
                                     f"float64's range")
        return impulse, c.reshape(m, len(mu)), np.array(mu, dtype=complex)

    def __call__(self, t: np.ndarray, input_names: Sequence[str]) -> np.ndarray:
        """u at times ``t`` [s] (shape (len(t), m)), the impulse excluded (zero for t > t0)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        _, c, mu = self.resolve(input_names, 0.0)
        return (np.exp(np.outer(t, mu)) @ c.T).real


def _number(value: object, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) \
            or not math.isfinite(float(value)):
        raise ArgumentError(what, f"expected a finite number, got {value!r:.60}")
    return float(value)


def _amplitude(value: Any, names: Sequence[str], kind: str) -> np.ndarray:
    m = len(names)
    what = f"{kind} amplitude"
    if isinstance(value, Mapping):
        out = np.zeros(m)
        index = {n: i for i, n in enumerate(names)}
        given: dict[int, str] = {}
        for key, val in value.items():
            i = index.get(key, index.get(f"u:{key}")) if isinstance(key, str) else None
            if i is None:
                raise ArgumentError(what, f"no input named {key!r:.60}; the model's inputs are "
                                          f"{', '.join(names) or '(none)'}")
            if i in given:
                raise ArgumentError(what, f"input '{names[i]}' given twice, as {given[i]!r} "
                                          f"and {key!r}")
            given[i] = key
            out[i] = _number(val, f"{what} of {key}")
        return out
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        if m != 1:
            raise ArgumentError(what, f"a single number needs a single-input model; this one "
                                      f"has {m} inputs: give {{name: value}} or {m} values")
        return np.array([_number(value, what)])
    arr = real_array(value, what, f"a mapping {{input name: value}}, {m} real values or a "
                                  "number")
    if arr.shape != (m,) or not np.all(np.isfinite(arr)):
        raise ArgumentError(what, f"expected {m} finite values (one per input: "
                                  f"{', '.join(names)}), got shape {arr.shape}")
    return arr


def step(amplitude: Amplitude) -> Signal:
    """u(t) = ``amplitude`` [N*m or N] from the first sample time on."""
    return Signal((_Part("step", amplitude),))


def impulse(amplitude: Amplitude) -> Signal:
    """A Dirac impulse of area ``amplitude`` [N*m*s or N*s] at the first sample time."""
    return Signal((_Part("impulse", amplitude),))


def harmonic(amplitude: Amplitude, w: float, phase: float = 0.0) -> Signal:
    """u(t) = ``amplitude`` sin(``w`` t + ``phase``): w [rad/s], phase [rad], t absolute [s].

    Raises:
        ArgumentError: ``w`` or ``phase`` not a finite number.
    """
    return Signal((_Part("harmonic", amplitude, _number(w, "w"), _number(phase, "phase")),))


__all__ = ["Signal", "harmonic", "impulse", "step"]
