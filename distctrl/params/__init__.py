"""Axis parameters: the declarative table, the internal-unit parameter set and the list format."""
from .axis import AxisParameters
from .listfile import ParameterList, format_list, load_list, parse_list_text
from .table import AXIS_PARAMETERS, BY_FIELD, BY_ID, BY_KEY, ParamSpec

__all__ = ["AxisParameters", "ParameterList", "format_list", "load_list", "parse_list_text",
           "AXIS_PARAMETERS", "BY_FIELD", "BY_ID", "BY_KEY", "ParamSpec"]
