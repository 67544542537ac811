"""distctrl.workbench.pages: the jinja2 environment of the HTML reports escapes as html.escape does
(the pages' bytes depend on it), escapes by default, passes markup and refuses missing values."""
from __future__ import annotations

import html

import pytest
from jinja2 import UndefinedError
from markupsafe import Markup

from distctrl.workbench.pages import environment, escape, fmt

TRICKY = "<script>alert('x') & \"y\"</script>"


def _render(source: str, **ctx) -> str:
    return environment().from_string(source).render(**ctx)


def test_values_are_escaped_by_default_like_html_escape():
    out = _render("<p title=\"{{ v }}\">{{ v }}</p>", v=TRICKY)
    assert out == f'<p title="{html.escape(TRICKY)}">{html.escape(TRICKY)}</p>'
    assert "&#x27;" in out and "&quot;" in out and "&#39;" not in out and "&#34;" not in out


def test_markup_and_macro_output_are_not_escaped_twice():
    assert _render("{{ v }}", v=Markup("<b>ok</b>")) == "<b>ok</b>"
    assert _render("{% macro m(x) %}<i>{{ x }}</i>{% endmacro %}{{ m('&') }}") == "<i>&amp;</i>"
    assert escape(escape("&")) == "&amp;"


def test_a_missing_value_is_an_error_not_an_empty_string():
    with pytest.raises(UndefinedError):
        _render("{{ nope }}")


def test_fmt_filter():
    assert _render("{{ a|fmt }} {{ b|fmt }} {{ c|fmt }} {{ d|fmt }}", a=1 / 3, b=None, c=True, d=float("nan")) \
        == "0.333333 – yes NaN"
    assert fmt(12345678.9) == "1.23457e+07"
