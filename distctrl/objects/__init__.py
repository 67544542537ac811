"""CNC objects of the axis-specific distance control (FCT-M3 §7.5/§7.6/§9.4, SPEC §10).

The registry :data:`AXIS_OBJECTS` is declared once in :mod:`distctrl.objects.registry`;
``docs/objects.md`` is generated from it (``python -m distctrl.objects.docgen``).
"""
from .registry import (ADS_PORT, ADS_TYPES, AXIS_OBJECTS, BY_ADDRESS, BY_LOW_OFFSET, BY_NAME, COLUMNS,
                       GENERAL_AXIS_OBJECTS, INDEX_GROUP, INDEX_GROUP_TF5200, INDEX_GROUPS, READ, SERVED_OBJECTS,
                       TF5200_OBJECTS,
                       READ_WRITE, TASK, AxisObjectContext, ObjectAccessError, ObjectSpec, ObjectValueError,
                       decode, encode, find_object, find_spec, format_object_table, format_value, index_offset,
                       object_table, read_bytes, read_value, write_bytes, write_value)

__all__ = ["ADS_PORT", "ADS_TYPES", "AXIS_OBJECTS", "BY_ADDRESS", "BY_LOW_OFFSET", "BY_NAME", "COLUMNS",
           "GENERAL_AXIS_OBJECTS", "INDEX_GROUP", "INDEX_GROUP_TF5200", "INDEX_GROUPS", "READ", "SERVED_OBJECTS",
           "TF5200_OBJECTS",
           "READ_WRITE", "TASK", "AxisObjectContext", "ObjectAccessError", "ObjectSpec", "ObjectValueError",
           "decode", "encode", "find_object", "find_spec", "format_object_table", "format_value", "index_offset",
           "object_table", "read_bytes", "read_value", "write_bytes", "write_value"]
