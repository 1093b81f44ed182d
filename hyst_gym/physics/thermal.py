"""Temperature: a(T) of eq. (4) and a lumped thermal model of the drive coil (eqs. (4) and (11)).

``a`` is proportional to absolute temperature, (4) ``a = Hh*T/Tc``, anchored so that
``a = a_ref`` (7012 A/m, the paper's room-temperature value) at ``T_ref``::

    a(T) = a_ref * T / T_ref

The transducer heats through Joule losses in its solenoid. The coil current follows the
applied field by (11), ``I = H/n``; one lumped heat capacity loses heat to ambient::

    C_th * T' = R_coil * I**2 - (T - T_amb(t)) / R_th,    T_amb(t) = T_amb0 + drift*t

Steady state under a constant power P: ``T = T_amb + R_th*P``; time constant ``R_th*C_th``.

Defaults (:class:`ThermalParams`) are a water-cooled actuator of the paper's size:
n = 1e4 turns/m (1150 turns on the 0.115 m rod), a 1 ohm coil, R_th = 0.2 K/W and
C_th = 600 J/K (rod, coil and housing), so the time constant is 120 s. Heavy driving,
a 1e5 A/m sine (10 A peak, 50 W mean), heats it by 10 K at steady state, which moves
``a`` by +3.4 % (7012 -> 7251 A/m): +2.2 % after two minutes, +3.1 % after five. The
paper's bounds [6300, 7300] A/m correspond to 263 K .. 305 K.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from .constants import PAPER_A, ROOM_TEMPERATURE
from .transducers import check_positive


@dataclass(frozen=True)
class ThermalParams:
    """Coil heating and the temperature law (4) of ``a``.

    Attributes
    ----------
    coil_resistance : float
        R, ohm (> 0).
    turns_per_meter : float
        n in (11) ``H = n*I``, 1/m (> 0).
    thermal_resistance : float
        R_th, from the transducer to ambient, K/W (> 0).
    heat_capacity : float
        C_th, J/K (> 0).
    reference_temperature : float
        T_ref at which ``a = a_reference``, K (> 0).
    a_reference : float
        a at T_ref, A/m (> 0). Paper: 7012.
    ambient_temperature : float
        T_amb at time 0, K (> 0).
    ambient_drift_rate : float
        d T_amb / dt, K/s (any sign; 0 = steady ambient).
    """

    coil_resistance: float = 1.0
    turns_per_meter: float = 1.0e4
    thermal_resistance: float = 0.2
    heat_capacity: float = 600.0
    reference_temperature: float = ROOM_TEMPERATURE
    a_reference: float = PAPER_A
    ambient_temperature: float = ROOM_TEMPERATURE
    ambient_drift_rate: float = 0.0

    def __post_init__(self):
        check_positive("ThermalParams", coil_resistance=self.coil_resistance,
                       turns_per_meter=self.turns_per_meter, thermal_resistance=self.thermal_resistance,
                       heat_capacity=self.heat_capacity, reference_temperature=self.reference_temperature,
                       a_reference=self.a_reference, ambient_temperature=self.ambient_temperature)
        if not (isinstance(self.ambient_drift_rate, (int, float, np.floating, np.integer))
                and math.isfinite(self.ambient_drift_rate)):
            raise ValueError(f"ThermalParams: ambient_drift_rate must be a finite number of K/s, "
                             f"got {self.ambient_drift_rate!r}")

    @property
    def time_constant(self) -> float:
        """``R_th*C_th``, s."""
        return self.thermal_resistance * self.heat_capacity

    def current(self, field):
        """Coil current I = H/n (A) for a field H (A/m), eq. (11)."""
        return np.asarray(field, dtype=np.float64) / self.turns_per_meter

    def joule_power(self, field):
        """Instantaneous Joule power ``R*(H/n)**2``, W."""
        current = self.current(field)
        return self.coil_resistance * current * current

    @property
    def power_per_square_field(self) -> float:
        """``R/n**2``: Joule power (W) per (A/m)^2 of applied field, from (11) ``I = H/n``."""
        return self.coil_resistance / self.turns_per_meter ** 2

    def ambient_at(self, time):
        """Ambient temperature (K) at ``time`` (s)."""
        return self.ambient_temperature + self.ambient_drift_rate * np.asarray(time, dtype=np.float64)

    def steady_temperature(self, power, ambient=None):
        """``T_amb + R_th*P`` (K) for a constant power P (W)."""
        ambient = self.ambient_temperature if ambient is None else ambient
        return ambient + self.thermal_resistance * np.asarray(power, dtype=np.float64)

    def replace(self, **changes) -> "ThermalParams":
        return dataclasses.replace(self, **changes)


# The laws below are plain arithmetic, written once: numpy code calls them on arrays, and
# their compiled twins (njit of the same function) serve the kernels of envs and diagnose,
# so a kernel and the array API give the same numbers bit for bit.


def a_law(a_reference, temperature, reference_temperature):
    """a(T) of eq. (4): ``a_reference*T/T_ref`` (A/m), proportional to the absolute temperature."""
    return a_reference * temperature / reference_temperature


def mean_square_linear(start, end):
    """Mean of ``h**2`` over a step on which ``h`` moves linearly from ``start`` to ``end``."""
    return (start * start + start * end + end * end) / 3.0


def temperature_step(temperature, ambient_start, ambient_end, offset, decay):
    """Exact step of ``tau*T' = -(T - T_amb(t)) + R_th*P`` for a power P held and an ambient
    linear over the step: ``T1 = Tp(t+dt) + (T0 - Tp(t))*decay`` with the particular
    solution ``Tp = T_amb + offset``, ``offset = R_th*P - drift*tau``, ``decay = exp(-dt/tau)``."""
    return (ambient_end + offset) + (temperature - (ambient_start + offset)) * decay


#: compiled twins of the laws above, for the njit kernels (inlined where they are called)
a_law_kernel = njit(cache=True, inline="always")(a_law)
mean_square_linear_kernel = njit(cache=True, inline="always")(mean_square_linear)
temperature_step_kernel = njit(cache=True, inline="always")(temperature_step)


def a_of_temperature(temperature, params: ThermalParams = ThermalParams()):
    """a(T) = a_ref*T/T_ref (A/m), eq. (4): proportional to the absolute temperature (K)."""
    temperature = np.asarray(temperature, dtype=np.float64)
    if np.any(~np.isfinite(temperature) | (temperature <= 0)):
        raise ValueError("a_of_temperature: temperature must be finite and > 0 K")
    result = np.asarray(a_law(params.a_reference, temperature, params.reference_temperature))
    return float(result) if result.ndim == 0 else result


def temperature_of_a(a, params: ThermalParams = ThermalParams()):
    """Inverse of :func:`a_of_temperature`: the temperature (K) at which the material has ``a`` (A/m)."""
    a = np.asarray(a, dtype=np.float64)
    if np.any(~np.isfinite(a) | (a <= 0)):
        raise ValueError("temperature_of_a: a must be finite and > 0 A/m")
    result = params.reference_temperature * a / params.a_reference
    return float(result) if result.ndim == 0 else result


def advance_temperature(temperature, field_start, field_end, dt, params: ThermalParams = ThermalParams(),
                        time: float = 0.0, ambient=None):
    """Temperature (K) after one step of ``dt`` s, for a batch of independent systems.

    The field (A/m) moves linearly from ``field_start`` to ``field_end`` over the step;
    the heating uses its mean Joule power ``R*mean(I**2)``, held over the step. With that
    power and a linear ambient the update is exact::

        T1 = Tp(t+dt) + (T0 - Tp(t)) * exp(-dt/tau),  Tp(t) = T_amb(t) + R_th*P - drift*tau

    Parameters
    ----------
    temperature : float or ndarray, shape (n,)
        Temperature at the start of the step, K.
    field_start, field_end : float or ndarray, shape (n,)
        Applied field at the two ends of the step, A/m.
    dt : float
        Step length, s (> 0).
    params : ThermalParams
    time : float
        Time at the start of the step, s (sets the drifting ambient).
    ambient : float or ndarray, optional
        Ambient temperature (K) to use instead of ``params``' drifting ambient, held over
        the step (e.g. a random walk drawn by the caller).

    Returns
    -------
    ndarray
        Temperature at the end of the step, K, broadcast over the inputs.
    """
    check_positive("advance_temperature", dt=dt)
    tau = params.time_constant
    power = params.power_per_square_field * mean_square_linear(np.asarray(field_start, dtype=np.float64),
                                                               np.asarray(field_end, dtype=np.float64))
    decay = math.exp(-dt / tau)
    temperature = np.asarray(temperature, dtype=np.float64)
    if ambient is None:
        drift = params.ambient_drift_rate
        ambient_start = params.ambient_temperature + drift * time
        ambient_end = ambient_start + drift * dt
        offset = params.thermal_resistance * power - drift * tau
    else:
        ambient_start = ambient_end = np.asarray(ambient, dtype=np.float64)
        offset = params.thermal_resistance * power
    return np.asarray(temperature_step(temperature, ambient_start, ambient_end, offset, decay))


__all__ = ["ROOM_TEMPERATURE", "ThermalParams", "a_law", "a_law_kernel", "a_of_temperature", "advance_temperature",
           "mean_square_linear", "mean_square_linear_kernel", "temperature_of_a", "temperature_step",
           "temperature_step_kernel"]
