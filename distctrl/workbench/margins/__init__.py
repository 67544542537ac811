"""Frequency domain of distance control: the linearised loop of one axis and its stability margins.

``distctrl margins SCENARIO`` (docs/margins.md). The loop is built with python-control as discrete
transfer functions in the GEO cycle ``T`` (the scenario's ``cycle_time``), from the very numbers the
cycle core and the virtual machine use:

* **filter** ``F(z)``: the coefficient buffer the core designs for the axis list's filter
  (:func:`distctrl.control.filters.design_coefficients`), read back as the transfer function the law
  computes (:func:`distctrl.control.law.filter_step`): MOVING_AVERAGE and EXPO_MEAN are FIR filters
  over the last n measurements, the Kalman filters FIR over the current one and the n before it
  (``K x + (1 - K) * prediction``), LOWPASS the Butterworth sections;
* **PID** on the offset step (:func:`distctrl.control.law.pid_step`):
  ``u = KP e + KP (T/T_n) e / (1 - z^-1) + g (m - m_prev)`` with the core's per-cycle D gain
  ``g = derivative_gain(KP, T_v, T)``, D on the measurement part ``m`` of the error;
* **offset integration** without the slope limiter: ``o_k = o_(k-1) + u_k``, i.e. ``1 / (1 - z^-1)``;
* **drive** (:class:`distctrl.sim.drive.Drive`): ``bus_delay_cycles`` of fieldbus delay, the P position
  loop ``kv`` and the velocity feed-forward ``ff`` discretised as the simulator does,
  ``X/C = z^-B ((kv T + ff) - ff z^-1) / (1 - (1 - kv T) z^-1)``; with a mechanical resonance
  (``resonance_hz`` f0, ``damping`` zeta) the sensor sees the nozzle ``N = R X`` with the simulator's
  exact discretisation ``R = 1 - (p12 / T) (1 - z^-1)^2 / (1 - tr(Phi) z^-1 + det(Phi) z^-2)``,
  ``Phi = expm(A T)`` (:func:`resonance_polynomials`), while the motor encoder (both encoders, SET_POS)
  reports ``X``;
* **dead time** of the measurement: one cycle because the machine's sensor reads the axis position of
  the previous cycle (:meth:`distctrl.sim.machine.Machine._step_axes` reads the sensor before the
  drives step), the sensor's ``delay_cycles``, and one more cycle when the list's
  ``optimized_scheduling`` (P-AXIS-00426) is off (the core then uses the reading of the last cycle);
* the **mode's feedback** (:func:`distctrl.control.law.feedback_value`, ``mode_error``): CONST_DIST with
  one encoder (the distance), with both encoders (P-AXIS-00500: ``d + c - a``), or SET_POS (the surface
  ``a - d`` against ``SET_POS + o``).

What the model leaves out (it is linear and small-signal): the slope limiter (v_max, a_max, the
braking bound ``sqrt(2 a |e|)``, the bounds of the offset), the drive's velocity and acceleration
limits, encoder and sensor quantisation, the sensor's range and noise. A loop the model calls
unstable grows until one of those limits it (a limit cycle whose amplitude and frequency the limits
decide, not the linear loop); a stable one settles from a small disturbance.

:func:`loop_model` reads a scenario (the tuning in force when the program first selects distance
control, e.g. the KP of the NC block), :func:`analyse` computes the margins
(:func:`control.stability_margins`) and the KP at the stability limit, :class:`MarginResult` prints,
exports (:meth:`MarginResult.to_dict`) and plots (:meth:`MarginResult.plot`, Bode and Nyquist).

The modules, by role (this face re-exports every name, so ``from distctrl.workbench.margins import ...``
works as before):

* ``model``: the constants, :class:`MarginsError`, :class:`LoopModel`, :func:`model_from_parts`,
  :func:`filter_coefficients`, :func:`resonance_polynomials`;
* ``scenario``: :func:`loop_model`, the loop of a scenario;
* ``analysis``: :func:`analyse` and :func:`kp_limit`;
* ``result``: :class:`MarginResult` (``to_dict``, ``to_csv``, ``format_text``, ``plot``);
* ``text``: the text ``distctrl margins`` prints.
"""
from __future__ import annotations

from ..plotfiles import PLOT_SUFFIXES
from .analysis import GRID_F_MIN_HZ, GRID_POINTS_PER_DECADE, analyse, kp_limit, phase_margin_deg  # noqa: F401
from .model import (KP_RANGE, KP_SEARCH_MAX, MAX_CROSSINGS_SHOWN, POLE_TOLERANCE, READ_DELAY_CYCLES,  # noqa: F401
                    SELECT_SEARCH_S, LoopModel, MarginsError, filter_coefficients, model_from_parts,
                    resonance_polynomials)
from .result import MarginResult, check_plot_path  # noqa: F401
from .scenario import loop_model

__all__ = ["MarginsError", "LoopModel", "MarginResult", "filter_coefficients", "loop_model", "analyse",
           "model_from_parts", "KP_SEARCH_MAX", "PLOT_SUFFIXES", "phase_margin_deg"]
