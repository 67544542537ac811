"""The serving layer (``distctrl serve``, docs/serve.md): the machine paced to wall-clock time and what
ADS and the live page share.

* :mod:`.machine`: :class:`~distctrl.serve.machine.ServedMachine` (the machine, its lock, the cycle
  thread, the run/stop switch, the services attached to it) and the session log;
* :mod:`.realtime`: the soft real-time cycle loop;
* :mod:`.net`: who may connect (``--allow``), for ADS and the page alike;
* :mod:`.session`: a session in the foreground until a duration, Ctrl-C or SIGTERM.

ADS (:class:`distctrl.ads.devices.AdsEndpoint`) and the live page (:class:`distctrl.ui.app.UiServer`)
attach to a served machine as equals; neither imports the other. This package imports neither.
"""
