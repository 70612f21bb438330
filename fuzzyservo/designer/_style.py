"""The designer page's sizes, colours and CSS, how many runs it compares at once, and
the HTML escaping its parts share."""

from __future__ import annotations

from matplotlib.colors import to_hex

from fuzzyservo.display import controller_colour

TERM_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
                "#7f7f7f", "#bcbd22", "#17becf")  # fmt: skip
REFERENCE_COLOUR = to_hex("tab:green")
MAX_COMPARED = 5
# sized for a 1,280 x 800 window (a laptop): sidebar, loop figures and metrics side by side,
# the tabs below as wide as the figures and metrics together; nothing scrolls sideways
SIDEBAR = 300
WIDTH = 560
METRICS_WIDTH = 370
TAB_WIDTH = WIDTH + METRICS_WIDTH + 10
CSS = """
.fs-metrics {overflow-x: auto;}
.fs-metrics table {border-collapse: collapse; font: 12px monospace;}
.fs-metrics td, .fs-metrics th {border-bottom: 1px solid #ddd; padding: 2px 5px; text-align: right;}
.fs-metrics td:first-child, .fs-metrics th:first-child {text-align: left;}
.fs-error {color: #b00020;}
"""
# a table's cells in the sidebar or beside a figure: small enough for six numbers in 370 px
DENSE_TABLE = (
    ".tabulator-cell, .tabulator-col-title {font-size: 12px;} .tabulator-cell {padding: 4px 3px;}"
)


def _colour(k: int) -> str:
    return to_hex(controller_colour(k))


def _esc(text: str) -> str:
    import html

    return html.escape(str(text), quote=True)
