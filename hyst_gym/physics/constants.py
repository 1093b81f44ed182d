"""The paper's numbers, written once: every layer imports them from here.

* ``ROOM_TEMPERATURE``: 20 degrees C in K, the reference temperature of a(T), eq. (4), and
  the default ambient;
* ``PAPER_A``: the anhysteretic parameter a at that temperature, A/m (§4);
* ``PAPER_DAMPING``, ``PAPER_STIFFNESS``, ``PAPER_COUPLING``: the identified coefficients
  chat, khat, zetahat of the lumped transducer (13), ``x'' + chat*x' + khat*x = zetahat*M``.
"""

#: 20 degrees C, in K
ROOM_TEMPERATURE = 293.15
#: a at ROOM_TEMPERATURE, A/m (the paper's §4 value)
PAPER_A = 7012.0

#: the paper's identified coefficients of (13)
PAPER_DAMPING = 7.8899e3       # chat, 1/s
PAPER_STIFFNESS = 6.4251e7     # khat, 1/s^2
PAPER_COUPLING = 1.3724e-2     # zetahat, (m/s^2)/(A/m)

__all__ = ["PAPER_A", "PAPER_COUPLING", "PAPER_DAMPING", "PAPER_STIFFNESS", "ROOM_TEMPERATURE"]
