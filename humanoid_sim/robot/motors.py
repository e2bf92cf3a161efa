"""A joint actuator's motor and gearbox: torque-speed envelope, current, power flow and winding temperature.

The motor is a DC-equivalent machine behind a gearbox of ratio N: motor speed = N * joint speed. Every function takes
joint-side time samples (torque tau in N m, speed omega in rad/s, optionally acceleration alpha in rad/s^2) and works
on whole arrays.

Conventions:

- Torque balance. The drive delivers the load torque ``tau`` plus the joint friction
  ``f(omega) = coulomb * sign(omega) + viscous * omega`` (zero static friction at omega = 0): ``tau_f = tau + f``.
  The gearbox passes ``tau_f`` with efficiency eta in the direction the power flows. Motoring (``tau_f * omega >= 0``,
  the motor drives the load; omega = 0 counts as motoring, the costlier side) needs the motor torque
  ``tau_f / (N eta)``; braking (``tau_f * omega < 0``, the load back-drives the motor) needs ``tau_f * eta / N``.
  The rotor's own inertia adds ``J_r N alpha`` ahead of the gearbox. Current ``I = motor torque / k_t``.
- Electrics. ``V = R(T) I + k_e N omega`` with ``k_e = k_t`` (SI units). The resistance follows the winding
  temperature, ``R(T) = R_ref (1 + alpha_Cu (T - T_ref))``. The terminal voltage is bounded by the bus,
  ``|V| <= U``, and the current by ``|I| <= I_max``; those two bounds make the torque-speed envelope.
- Power. ``P_elec = V I`` is the sum of the load power ``tau omega``, the friction and gear losses (both >= 0), the
  rotor's kinetic-energy rate and the copper loss ``I^2 R(T)``. ``P_elec < 0`` is regeneration: the net energy counts
  it as returned to the bus, the drawn energy ``sum(max(P_elec, 0) dt)`` assumes a bus that absorbs nothing.
- Heat. One RC from winding to ambient: ``C_th dT/dt = R(T) I^2 - (T - T_amb) / R_th``. The current is held over each
  sample's step, and the update is exact for that (linear in T, so one exponential per step), never forward Euler.
- DC-equivalent constants. ``k_t``, ``R`` and the currents are those of a DC motor with the same torque, copper loss
  and back-EMF (maxon's datasheet convention: terminal resistance phase to phase). ``models/actuators.yaml`` converts
  each source's field-oriented constants to it.

MuJoCo's ``dcmotor`` is this machine without gearbox efficiency and Coulomb friction (docs/notes/2026-11-26-motors.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import yaml
from numpy.typing import ArrayLike, NDArray

from humanoid_sim.errors import InputError
from humanoid_sim.paths import MODELS_DIR

Array = NDArray[np.float64]
CATALOGUE = MODELS_DIR / "actuators.yaml"
"""The shipped catalogue of sourced actuators."""
ALPHA_COPPER = 0.00393
"""Temperature coefficient of copper's resistance near 20 deg C (1/K)."""


@dataclass(frozen=True)
class MotorSpec:
    """One joint actuator: a motor, its gearbox, its drive's limits and its heat path (joint side = gearbox output).

    Attributes:
        gear_ratio: N (-): motor speed / joint speed.
        rotor_inertia: J_r (kg m^2): the rotor's inertia about its spin axis, motor side.
        efficiency: eta (-): gearbox efficiency, the same in both power-flow directions.
        coulomb_friction: joint-side Coulomb friction (N m).
        viscous_friction: joint-side viscous friction (N m s/rad).
        torque_constant: k_t (N m/A), also the back-EMF constant k_e (V s/rad).
        resistance: R (ohm) at ``reference_temperature``, phase to phase (DC-equivalent).
        bus_voltage: U (V): the largest terminal voltage magnitude the drive applies.
        peak_current: I_max (A): the drive's current limit.
        continuous_current: I_cont (A): the current the motor carries indefinitely at its rated cooling.
        thermal_resistance: R_th (K/W), winding to ambient.
        thermal_capacitance: C_th (J/K) of the winding node.
        ambient_temperature: T_amb (deg C).
        max_winding_temperature: the winding's temperature limit (deg C).
        reference_temperature: T_ref (deg C) at which ``resistance`` holds.
        temperature_coefficient: alpha_Cu (1/K) of the resistance; 0 keeps R constant.
        name: a label for messages and reports.
    """

    gear_ratio: float
    rotor_inertia: float
    efficiency: float
    coulomb_friction: float
    viscous_friction: float
    torque_constant: float
    resistance: float
    bus_voltage: float
    peak_current: float
    continuous_current: float
    thermal_resistance: float
    thermal_capacitance: float
    ambient_temperature: float
    max_winding_temperature: float
    reference_temperature: float = 25.0
    temperature_coefficient: float = ALPHA_COPPER
    name: str = ""

    def __post_init__(self) -> None:
        positive = ("gear_ratio", "torque_constant", "resistance", "bus_voltage", "peak_current",
                    "continuous_current", "thermal_resistance", "thermal_capacitance")
        non_negative = ("rotor_inertia", "coulomb_friction", "viscous_friction", "temperature_coefficient")
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name == "name":
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                self._fail(f.name, value, "a finite number")
            if f.name in positive and value <= 0:
                self._fail(f.name, value, "> 0")
            if f.name in non_negative and value < 0:
                self._fail(f.name, value, ">= 0")
        for bad, field, expected in (
                (not 0 < self.efficiency <= 1, "efficiency", "0 < efficiency <= 1"),
                (self.continuous_current > self.peak_current, "continuous_current",
                 f"<= peak_current ({self.peak_current!r} A)"),
                (self.max_winding_temperature <= self.ambient_temperature, "max_winding_temperature",
                 f"> ambient_temperature ({self.ambient_temperature!r} deg C)")):
            if bad:
                self._fail(field, getattr(self, field), expected)

    def _fail(self, field: str, value: object, expected: str) -> None:
        label = f"MotorSpec {self.name!r}" if self.name else "MotorSpec"
        raise InputError(f"{label}: {field} is {value!r}; expected {expected}")

    @property
    def reflected_inertia(self) -> float:
        """The rotor's inertia seen at the joint, N^2 J_r (kg m^2)."""
        return self.gear_ratio**2 * self.rotor_inertia

    @property
    def no_load_speed(self) -> float:
        """The joint speed at which the back-EMF equals the bus voltage, U / (k_t N) (rad/s)."""
        return self.bus_voltage / (self.torque_constant * self.gear_ratio)

    @property
    def stall_torque(self) -> float:
        """The joint torque at zero speed, N eta k_t min(I_max, U / R_ref) (N m)."""
        current = min(self.peak_current, self.bus_voltage / self.resistance)
        return self.gear_ratio * self.efficiency * self.torque_constant * current

    @property
    def thermal_time_constant(self) -> float:
        """R_th C_th (s): the winding's time constant at constant resistance."""
        return self.thermal_resistance * self.thermal_capacitance


class TorqueEnvelope(NamedTuple):
    """The load torques the drive can deliver at each joint speed (N m): ``tau_min <= tau <= tau_max``."""

    omega: Array
    tau_min: Array
    tau_max: Array


class Saturation(NamedTuple):
    """A torque command clipped to the envelope: the torque delivered (N m), where the command lay outside, and the
    shortfall = command - delivered (N m, zero where not saturated)."""

    torque: Array
    saturated: NDArray[np.bool_]
    shortfall: Array


@dataclass(frozen=True)
class PowerFlow:
    """Where the electrical power goes, per sample (W): ``electrical`` = V I (negative: regenerated into the bus) is
    the sum of ``load`` = tau omega, the losses ``friction`` = f(omega) omega >= 0, ``gear`` >= 0 and
    ``copper`` = I^2 R(T), and ``rotor``, the rate of change of the rotor's kinetic energy (see :meth:`residual`)."""

    load: Array
    friction: Array
    gear: Array
    rotor: Array
    copper: Array
    electrical: Array

    def residual(self) -> float:
        """The largest |electrical - (load + friction + gear + rotor + copper)| over the samples (W)."""
        parts = self.load + self.friction + self.gear + self.rotor + self.copper
        return float(np.max(np.abs(self.electrical - parts), initial=0.0))


def _arr(x: ArrayLike) -> Array:
    return np.asarray(x, dtype=float)


def _friction(spec: MotorSpec, omega: Array) -> Array:
    return spec.coulomb_friction * np.sign(omega) + spec.viscous_friction * omega


def resistance_at(spec: MotorSpec, temperature: ArrayLike | None = None) -> Array:
    """The winding resistance R(T) = R_ref (1 + alpha_Cu (T - T_ref)) (ohm); ``None`` means T_ref."""
    if temperature is None:
        return _arr(spec.resistance)
    return spec.resistance * (1 + spec.temperature_coefficient * (_arr(temperature) - spec.reference_temperature))


def motor_torque(spec: MotorSpec, tau: ArrayLike, omega: ArrayLike, accel: ArrayLike | None = None) -> Array:
    """The motor torque (N m, motor side) that delivers the load torque ``tau`` at joint speed ``omega``.

    Args:
        spec: the actuator.
        tau: load torque at the joint (N m): what the joint needs, without the actuator's own friction and rotor.
        omega: joint speed (rad/s).
        accel: joint acceleration (rad/s^2) for the rotor's inertia torque; ``None`` when ``tau`` already holds the
            reflected inertia (a dynamics model with armature N^2 J_r).
    """
    omega = _arr(omega)
    tau_f = _arr(tau) + _friction(spec, omega)
    n, eta = spec.gear_ratio, spec.efficiency
    torque = np.where(tau_f * omega >= 0, tau_f / (n * eta), tau_f * eta / n)
    if accel is not None:
        torque = torque + spec.rotor_inertia * n * _arr(accel)
    return torque


def motor_current(spec: MotorSpec, tau: ArrayLike, omega: ArrayLike, accel: ArrayLike | None = None) -> Array:
    """The winding current (A) for the load torque ``tau`` at ``omega``: :func:`motor_torque` / k_t."""
    return motor_torque(spec, tau, omega, accel) / spec.torque_constant


def joint_torque(spec: MotorSpec, current: ArrayLike, omega: ArrayLike, accel: ArrayLike | None = None) -> Array:
    """The load torque (N m) a current delivers at ``omega``: the inverse of :func:`motor_current`."""
    omega = _arr(omega)
    n, eta = spec.gear_ratio, spec.efficiency
    torque = spec.torque_constant * _arr(current)
    if accel is not None:
        torque = torque - spec.rotor_inertia * n * _arr(accel)
    # the gearbox's output torque has the motor torque's sign, so its sign against omega picks the power flow
    tau_f = np.where(torque * omega >= 0, torque * n * eta, torque * n / eta)
    return tau_f - _friction(spec, omega)


def terminal_voltage(spec: MotorSpec, current: ArrayLike, omega: ArrayLike,
                     temperature: ArrayLike | None = None) -> Array:
    """The terminal voltage V = R(T) I + k_t N omega (V) that drives ``current`` at joint speed ``omega``."""
    return (resistance_at(spec, temperature) * _arr(current)
            + spec.torque_constant * spec.gear_ratio * _arr(omega))


def current_at_voltage(spec: MotorSpec, voltage: ArrayLike, omega: ArrayLike,
                       temperature: ArrayLike | None = None) -> Array:
    """The current (A) a terminal voltage drives at joint speed ``omega``: (V - k_t N omega) / R(T)."""
    back_emf = spec.torque_constant * spec.gear_ratio * _arr(omega)
    return (_arr(voltage) - back_emf) / resistance_at(spec, temperature)


def torque_envelope(spec: MotorSpec, omega: ArrayLike, temperature: ArrayLike | None = None,
                    accel: ArrayLike | None = None) -> TorqueEnvelope:
    """The load-torque interval the drive can deliver at each joint speed (and acceleration, for the rotor).

    The current lies in ``[max(-I_max, (-U - k_t N omega) / R), min(I_max, (U - k_t N omega) / R)]`` (the bus bounds
    the terminal voltage, the drive bounds the current) and maps to the load torque through :func:`joint_torque`,
    which is increasing in the current. Beyond ``(U + R I_max) / (k_t N)`` no current within I_max is reachable and
    ``tau_min > tau_max``: :func:`saturate` then gives ``tau_max``, the torque at the full bus voltage, whose current
    exceeds I_max (the load drives the joint faster than the drive can hold). ``omega`` in rad/s; ``temperature``
    (deg C) sets R(T), ``None`` meaning the reference temperature; ``accel`` (rad/s^2) as in :func:`motor_torque`.
    """
    omega = _arr(omega)
    r = resistance_at(spec, temperature)
    back_emf = spec.torque_constant * spec.gear_ratio * omega
    i_hi = np.minimum(spec.peak_current, (spec.bus_voltage - back_emf) / r)
    i_lo = np.maximum(-spec.peak_current, (-spec.bus_voltage - back_emf) / r)
    return TorqueEnvelope(omega, joint_torque(spec, i_lo, omega, accel), joint_torque(spec, i_hi, omega, accel))


def saturate(spec: MotorSpec, tau_cmd: ArrayLike, omega: ArrayLike, temperature: ArrayLike | None = None,
             accel: ArrayLike | None = None) -> Saturation:
    """Clip a load-torque command (N m) to the envelope at ``omega``; see :func:`torque_envelope`."""
    tau_cmd = _arr(tau_cmd)
    env = torque_envelope(spec, omega, temperature, accel)
    torque = np.minimum(np.maximum(tau_cmd, env.tau_min), env.tau_max)
    shortfall = tau_cmd - torque
    return Saturation(torque, shortfall != 0, shortfall)


def power_flow(spec: MotorSpec, tau: ArrayLike, omega: ArrayLike, accel: ArrayLike | None = None,
               temperature: ArrayLike | None = None) -> PowerFlow:
    """The drive's power balance per sample (W); arguments as in :func:`motor_current` and :func:`resistance_at`."""
    tau, omega = np.broadcast_arrays(_arr(tau), _arr(omega))
    n, friction = spec.gear_ratio, _friction(spec, omega)
    gear_in = motor_torque(spec, tau, omega) * n * omega      # shaft power into the gearbox
    rotor = np.zeros_like(omega) if accel is None else spec.rotor_inertia * n * _arr(accel) * n * omega
    current = motor_current(spec, tau, omega, accel)
    volts = terminal_voltage(spec, current, omega, temperature)
    return PowerFlow(load=tau * omega, friction=friction * omega, gear=gear_in - (tau + friction) * omega,
                     rotor=rotor, copper=current**2 * resistance_at(spec, temperature), electrical=volts * current)


def winding_temperature(spec: MotorSpec, current: ArrayLike, dt: ArrayLike,
                        initial: float | None = None) -> Array:
    """The winding temperature (deg C) at the end of each sample's step, from ``initial`` (default: ambient).

    The current ``current[k]`` (A) is held over the step ``dt[k]`` (s; a scalar for a uniform step). With
    theta = T - T_amb the heat balance is ``dtheta/dt = a - b theta``, where
    ``a = R(T_amb) I^2 / C_th`` and ``b = (1/R_th - alpha_Cu R_ref I^2) / C_th``, linear for a held current, so
    ``theta' = theta e^{-b h} + a h phi(-b h)`` with ``phi(x) = (e^x - 1)/x`` is exact. ``b < 0`` (a current past the
    thermal-runaway current ``1 / sqrt(alpha_Cu R_ref R_th)``) grows without bound, as the physics does.
    """
    current = _arr(current).ravel()
    h = np.broadcast_to(_arr(dt), current.shape).astype(float)
    i2 = current**2
    c = spec.thermal_capacitance
    a = resistance_at(spec, spec.ambient_temperature) * i2 / c
    b = (1 / spec.thermal_resistance - spec.temperature_coefficient * spec.resistance * i2) / c
    x = -b * h
    small = np.abs(x) < 1e-12
    phi = np.where(small, 1.0, np.expm1(x) / np.where(small, 1.0, x))
    decay, gain = np.exp(x).tolist(), (a * h * phi).tolist()
    theta = (spec.ambient_temperature if initial is None else initial) - spec.ambient_temperature
    out = []
    for d, g in zip(decay, gain):      # a first-order recurrence: sequential by nature, cheap per sample
        theta = d * theta + g
        out.append(theta)
    return np.asarray(out) + spec.ambient_temperature


@dataclass(frozen=True)
class MotorReport:
    """One joint's actuator over a profile. Margins are fractions: >= 0 passes, < 0 says by how much it fails.

    Attributes:
        name: the actuator's name.
        duration: the profile's length (s).
        peak_current: max |I| (A).
        rms_current: the time-weighted RMS current (A).
        rms_ratio: rms_current / I_cont (-).
        peak_temperature: the hottest winding temperature (deg C).
        temperature_limit: the winding's limit (deg C).
        torque_margin: min over samples of the distance to the envelope (N m) / stall torque.
        speed_margin: 1 - max |omega| / no-load speed.
        current_margin: 1 - peak_current / I_max.
        rms_margin: 1 - rms_ratio: a periodic gait repeated long enough heats to the RMS current's steady state.
        temperature_margin: 1 - (peak_temperature - T_amb) / (limit - T_amb).
        energy_net: sum of P_elec dt (J), regeneration counted as returned.
        energy_drawn: sum of max(P_elec, 0) dt (J): a bus that absorbs no regenerated energy.
        saturated_fraction: the fraction of the samples outside the envelope.
    """

    name: str
    duration: float
    peak_current: float
    rms_current: float
    rms_ratio: float
    peak_temperature: float
    temperature_limit: float
    torque_margin: float
    speed_margin: float
    current_margin: float
    rms_margin: float
    temperature_margin: float
    energy_net: float
    energy_drawn: float
    saturated_fraction: float

    @property
    def failures(self) -> list[str]:
        """The checks that fail, each with its margin."""
        return [f"{m.removesuffix('_margin')}: margin {getattr(self, m):.3g}"
                for m in ("torque_margin", "speed_margin", "current_margin", "rms_margin", "temperature_margin")
                if getattr(self, m) < 0]

    @property
    def passed(self) -> bool:
        """All margins >= 0."""
        return not self.failures


def assess(spec: MotorSpec, tau: ArrayLike, omega: ArrayLike, dt: ArrayLike, accel: ArrayLike | None = None,
           initial_temperature: float | None = None) -> MotorReport:
    """Check an actuator against a joint's torque and speed profile.

    Args:
        spec: the actuator.
        tau: load torque per sample (N m), as in :func:`motor_current`.
        omega: joint speed per sample (rad/s).
        dt: each sample's step (s), or one uniform step.
        accel: joint acceleration per sample (rad/s^2), or ``None`` (see :func:`motor_torque`).
        initial_temperature: the winding's temperature before the first sample (deg C); default ambient.
    """
    tau, omega = np.broadcast_arrays(_arr(tau).ravel(), _arr(omega).ravel())
    h = np.broadcast_to(_arr(dt), tau.shape).astype(float)
    if tau.size == 0 or np.any(h <= 0):
        raise InputError(f"assess: {tau.size} samples with steps from {h.min(initial=0.0)!r} s; "
                         "expected at least one sample and positive steps")
    current = motor_current(spec, tau, omega, accel)
    temp_end = winding_temperature(spec, current, h, initial_temperature)
    temp_start = np.concatenate(([spec.ambient_temperature if initial_temperature is None else initial_temperature],
                                 temp_end[:-1]))
    env = torque_envelope(spec, omega, temp_start, accel)
    distance = np.minimum(env.tau_max - tau, tau - env.tau_min)
    p_elec = power_flow(spec, tau, omega, accel, temp_start).electrical
    duration = float(h.sum())
    rms = math.sqrt(float(np.sum(current**2 * h)) / duration)
    peak_temp = float(max(temp_end.max(), temp_start[0]))
    rise_allowed = spec.max_winding_temperature - spec.ambient_temperature
    return MotorReport(
        name=spec.name, duration=duration, peak_current=float(np.max(np.abs(current))), rms_current=rms,
        rms_ratio=rms / spec.continuous_current, peak_temperature=peak_temp,
        temperature_limit=spec.max_winding_temperature,
        torque_margin=float(distance.min()) / spec.stall_torque,
        speed_margin=1 - float(np.max(np.abs(omega))) / spec.no_load_speed,
        current_margin=1 - float(np.max(np.abs(current))) / spec.peak_current,
        rms_margin=1 - rms / spec.continuous_current,
        temperature_margin=1 - (peak_temp - spec.ambient_temperature) / rise_allowed,
        energy_net=float(np.sum(p_elec * h)), energy_drawn=float(np.sum(np.maximum(p_elec, 0) * h)),
        saturated_fraction=float(np.mean(distance < 0)))


def load_catalogue(path: str | Path | None = None) -> dict[str, MotorSpec]:
    """The actuators of a catalogue file (default: the shipped ``models/actuators.yaml``), by name.

    Each entry maps every numeric :class:`MotorSpec` field to ``{value: <number>, source: <text>}``; an entry may also
    hold ``description`` and ``sources``.

    Raises:
        InputError: a missing file or field, a field without its source, an unknown field, or an invalid value.
    """
    path = Path(CATALOGUE if path is None else path)
    try:
        data: Any = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise InputError(f"actuator catalogue: cannot read {str(path)!r} ({exc}); expected a YAML file") from exc
    if not isinstance(data, dict) or not data:
        raise InputError(f"actuator catalogue {str(path)!r}: expected a mapping of actuator names to entries")
    numeric = [f.name for f in fields(MotorSpec) if f.name != "name"]
    specs = {}
    for name, entry in data.items():
        where = f"actuator catalogue {str(path)!r}, {name!r}"
        if not isinstance(entry, dict):
            raise InputError(f"{where}: expected a mapping of fields, got {entry!r}")
        unknown = set(entry) - set(numeric) - {"description", "sources"}
        if unknown:
            raise InputError(f"{where}: unknown field(s) {sorted(unknown)}; expected {numeric}")
        values: dict[str, Any] = {}
        for field in numeric:
            item = entry.get(field)
            if not (isinstance(item, dict) and "value" in item and str(item.get("source") or "").strip()):
                raise InputError(f"{where}: {field} is {item!r}; expected {{value: <number>, source: <text>}}")
            values[field] = item["value"]
        specs[name] = MotorSpec(**values, name=str(name))
    return specs


__all__ = ["ALPHA_COPPER", "CATALOGUE", "MotorReport", "MotorSpec", "PowerFlow", "Saturation", "TorqueEnvelope",
           "assess", "current_at_voltage", "joint_torque", "load_catalogue", "motor_current", "motor_torque",
           "power_flow", "resistance_at", "saturate", "terminal_voltage", "torque_envelope", "winding_temperature"]
