"""Every filter type is described once (control/filters.FILTER_KINDS) and the others read it."""
from __future__ import annotations

from distctrl.base.kinds import FILTER_TYPE_NAMES, FilterType
from distctrl.control import law
from distctrl.control.filters import FILTER_KINDS, FILTER_PARAMS, FilterConfig, design_coefficients
from distctrl.tuning import space
from distctrl.workbench import filters as wb
from distctrl.workbench.margins import filter_coefficients


def test_every_filter_type_has_a_descriptor():
    assert set(FILTER_KINDS) == set(FilterType)
    assert all(k.type == t for t, k in FILTER_KINDS.items())


def test_the_descriptor_params_are_filter_parameters():
    for kind in FILTER_KINDS.values():
        assert set(kind.params) <= set(FILTER_PARAMS), kind.type


def test_every_documented_type_can_be_designed_and_a_linear_one_has_a_model_for_the_margins():
    for name in FILTER_TYPE_NAMES:
        fc = design_coefficients(FilterConfig(FilterType[name], 5, 0.5, 10.0, 2, 30.0), 0.001)
        if FILTER_KINDS[FilterType(int(fc[law.FC_KIND]))].polynomials is None:
            continue                                            # not linear (e.g. an order statistic)
        b, a = filter_coefficients(fc)
        assert abs(sum(b) / sum(a) - 1.0) < 1e-9, name          # unit DC gain: no offset from filtering


def test_the_law_codes_the_descriptors_give_are_the_law_s():
    codes = {int(t) for t in FilterType if t != FilterType.DEFAULT}      # the FilterType value is the law's code
    assert {law.PASS, law.MOVING_AVERAGE, law.EXPO_MEAN, law.LOWPASS, law.KALMAN_MA, law.KALMAN_EXPO} <= codes
    for t in FilterType:
        assert FILTER_KINDS[t].code(FilterConfig(t, 5, 0.5, 10.0, 2, 30.0)) in codes


def test_workbench_and_tuning_read_the_descriptors():
    for t, kind in FILTER_KINDS.items():
        if t != FilterType.PASS:
            assert wb.KEYS_BY_TYPE[t] == kind.params
            assert space.filter_fields(t) == kind.fields
    assert space.DEFAULT_SPACE[0].choices == tuple(t for t, k in FILTER_KINDS.items() if k.tunable)
    assert set(wb.DEFAULT_SPECS) == {k.example for k in FILTER_KINDS.values() if k.example}
