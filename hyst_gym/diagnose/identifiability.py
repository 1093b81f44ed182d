"""What each channel set can tell apart, and which measurement separates what it cannot.

A recording holds the field (or the coil current) and one or both outputs: magnetization M
and tip displacement x. The three channel sets see different things:

* **magnetization only** -- the hysteresis itself. Effects that act on the mechanics
  (``quadratic_magnetostriction``, ``rod_dynamics``, ``delta_e``) cannot show.
* **displacement only** -- M is seen through the mechanics. A lag of the displacement sensor,
  a rod mode above the first resonance and eddy-current loss all add phase lag that grows
  with frequency; a bias field, a different anhysteretic curve and an M^2 law all bend the
  static x-H curve. Which of them is present is then a question of degree, not of kind.
* **both** -- M pins the hysteresis, so what is left in x is mechanical, and a lag seen in
  M too is magnetic (eddy currents) or a sensor lag common to both.

``CONFUSABLE`` lists, per channel set, the pairs of vocabulary effects whose signatures
overlap, with the measurement that would separate them. The decision stage uses it to word
an ``ambiguous`` verdict; it never uses it to pick a winner.
"""

from __future__ import annotations

CHANNEL_SETS = ("magnetization", "displacement", "both")

#: Effects that act on the displacement path only (invisible in a magnetization-only record).
MECHANICAL_EFFECTS = ("quadratic_magnetostriction", "rod_dynamics", "delta_e")
#: Effects whose signature needs a real time axis (rate, delay or resonance).
RATE_EFFECTS = ("eddy_current", "sensor_lag", "rod_dynamics")

_RECORD_M = "record the magnetization (a pick-up coil) beside the displacement"
_BROADBAND = "excite above the first resonance (a broadband or chirp drive up to the sensor's Nyquist frequency)"
_TEMPERATURE = "record the coil or rod temperature"
_AMPLITUDES = "record loops at several amplitudes, down to a tenth of the largest (small loops show the low-field susceptibility)"
_SLOW = "repeat the record at a lower and a higher drive frequency (rate effects scale with frequency)"

CONFUSABLE = {
    "magnetization": {
        frozenset({"eddy_current", "sensor_lag"}): _SLOW + "; a sensor lag is a fixed delay, eddy loss widens the loop",
        frozenset({"field_bias", "anhysteretic_shape"}): "record a loop symmetric about H = 0 at two amplitudes",
        frozenset({"thermal_drift", "anhysteretic_shape"}): _TEMPERATURE,
        frozenset({"small_loop", "anhysteretic_shape"}): _AMPLITUDES,
        frozenset({"small_loop", "field_bias"}): _AMPLITUDES,
    },
    "displacement": {
        frozenset({"small_loop", "anhysteretic_shape"}): _AMPLITUDES + ", and " + _RECORD_M,
        frozenset({"small_loop", "quadratic_magnetostriction"}): _RECORD_M,
        frozenset({"small_loop", "delta_e"}): _RECORD_M,
        frozenset({"small_loop", "field_bias"}): _RECORD_M,
        frozenset({"sensor_lag", "rod_dynamics"}): _BROADBAND + ", or " + _RECORD_M,
        frozenset({"sensor_lag", "eddy_current"}): _RECORD_M,
        frozenset({"rod_dynamics", "eddy_current"}): _RECORD_M,
        frozenset({"field_bias", "quadratic_magnetostriction"}): _RECORD_M,
        frozenset({"field_bias", "anhysteretic_shape"}): _RECORD_M,
        frozenset({"quadratic_magnetostriction", "anhysteretic_shape"}): _RECORD_M,
        frozenset({"delta_e", "quadratic_magnetostriction"}): _RECORD_M + ", and " + _BROADBAND,
        frozenset({"delta_e", "anhysteretic_shape"}): _RECORD_M,
        frozenset({"delta_e", "field_bias"}): _RECORD_M,
        frozenset({"thermal_drift", "anhysteretic_shape"}): _TEMPERATURE,
        frozenset({"thermal_drift", "delta_e"}): _TEMPERATURE,
    },
    "both": {
        frozenset({"sensor_lag", "rod_dynamics"}): _BROADBAND,
        frozenset({"delta_e", "rod_dynamics"}): _BROADBAND + " at two bias fields",
        frozenset({"small_loop", "anhysteretic_shape"}): _AMPLITUDES,
        frozenset({"thermal_drift", "anhysteretic_shape"}): _TEMPERATURE,
    },
}


def channel_set(channels) -> str:
    """``"magnetization"``, ``"displacement"`` or ``"both"`` for a recording's output channels."""
    channels = set(channels)
    if channels == {"magnetization", "displacement"}:
        return "both"
    if channels in ({"magnetization"}, {"displacement"}):
        return next(iter(channels))
    raise ValueError(f"a recording needs magnetization and/or displacement, got {sorted(channels)}")


def separating_measurement(channels, effects) -> str:
    """The measurements that would tell ``effects`` (two or more) apart in this channel set."""
    table = CONFUSABLE[channel_set(channels)]
    effects = sorted(effects)
    advice = []
    for i, first in enumerate(effects):
        for second in effects[i + 1:]:
            text = table.get(frozenset({first, second}))
            if text is None:
                text = ("refit on a longer record with a richer drive (minor loops, several rates): "
                        "the two fit this one equally well")
            if text not in advice:
                advice.append(text)
    return "; ".join(advice)


def invisible_effects(channels) -> tuple:
    """Vocabulary effects this channel set cannot show at all."""
    return MECHANICAL_EFFECTS if channel_set(channels) == "magnetization" else ()


__all__ = ["CHANNEL_SETS", "CONFUSABLE", "MECHANICAL_EFFECTS", "RATE_EFFECTS", "channel_set",
           "invisible_effects", "separating_measurement"]
