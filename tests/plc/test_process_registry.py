"""Process functions declare their own keys (Klipper style); config.py is a loop over the registry."""
from __future__ import annotations

import pytest

from distctrl.plc.process import PROCESS_CLASSES, PROCESS_KEYS, ProcessFunction
from distctrl.errors.config import ConfigError


def test_the_registry_names_each_class_by_its_name_and_the_keys_are_the_declared_ones():
    for name, cls in PROCESS_CLASSES.items():
        assert issubclass(cls, ProcessFunction) and cls.name == name
        assert PROCESS_KEYS[name] == tuple(cls.KEYS)
        assert callable(cls.from_config) and callable(cls.build)


@pytest.mark.parametrize("name", sorted(PROCESS_CLASSES))
def test_every_declared_default_lies_in_the_declared_range(name):
    for key_name, key in PROCESS_CLASSES[name].KEYS.items():
        if key.default is not None and key.kind in ("number", "int"):
            assert key.check(key.default, key_name) == key.default


@pytest.mark.parametrize("name", sorted(PROCESS_CLASSES))
def test_a_value_outside_the_declared_range_is_refused_naming_the_key(name):
    for key_name, key in PROCESS_CLASSES[name].KEYS.items():
        if key.kind in ("number", "int") and key.lo is not None:
            with pytest.raises(ConfigError, match=f"process\\[0\\].{key_name}"):
                key.check(key.lo - 1, f"process[0].{key_name}")


def test_the_cnc_hooks_are_declared_attributes():
    assert ProcessFunction.declares == ()
    for cls in PROCESS_CLASSES.values():
        assert isinstance(cls.declares, tuple)
