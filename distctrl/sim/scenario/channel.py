"""``[channel]``: the channel parameter list (3D distance control) and the head kinematics
(docs/run-3d.md)."""
from __future__ import annotations

from pathlib import Path

from distctrl.errors import ParameterError
from distctrl.errors.config import ConfigError, require_choice, require_mapping
from distctrl.params.channel import ChannelParameters, load_channel_list

from .axes import AxisConfig
from .common import _file

#: [channel]: the kernel channel list (3D distance control) and the head kinematics
CHANNEL_KEYS = ("params", "kinematics")
#: head kinematics a channel may have: "CA" (5-axis CA head, kinematic ID 9) or "none"
KINEMATICS = ("CA", "none")
#: the axes the CA head needs
CA_AXES = ("X", "Y", "Z", "A", "C")


def _channel_config(cfg: object, axes: dict[str, AxisConfig], base_dir: Path
                    ) -> tuple[ChannelParameters | None, Path | None, tuple[str, ...], str | None]:
    """``[channel]``: (channel parameters, their file, loader warnings, kinematics or None)."""
    key = "channel"
    require_mapping(cfg, key, CHANNEL_KEYS)
    assert isinstance(cfg, dict)
    params, params_file, warnings = None, None, ()
    if "params" in cfg:
        params_file = _file(cfg["params"], f"{key}.params", base_dir,
                            "channel parameter list (kernel format)")
        try:
            plist = load_channel_list(params_file)
        except ParameterError as exc:
            exc.scenario_key = f"{key}.params"  # type: ignore[attr-defined]  # see _with_source
            raise
        params, warnings = plist.params, tuple(plist.warnings)
    missing = [a for a in CA_AXES if a not in axes]
    if "kinematics" in cfg:
        value = cfg["kinematics"]
        kin = require_choice(value.upper() if isinstance(value, str) and value.upper() == "CA" else value,
                             f"{key}.kinematics", KINEMATICS)
        if kin == "CA" and missing:
            raise ConfigError(f"{key}.kinematics", value, "'CA' only with the axes X, Y, Z, A and C "
                              f"configured (missing: {', '.join(missing)}); or 'none'", "axes missing for")
    else:
        kin = "CA" if not missing else "none"
    return params, params_file, warnings, (None if kin == "none" else kin)
