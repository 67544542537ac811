"""Workbench tools: offline analysis helpers around the cycle core, one module per tool
(e.g. ``distctrl.workbench.filters``: ``distctrl filters``); see docs/workbench-*.md.

Deliberately empty: import the tool modules directly.
"""
