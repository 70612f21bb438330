"""JSON output files: strict JSON (NaN and inf become null), numpy numbers as Python ones."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any


def json_ready(obj: Any) -> Any:
    """NaN and inf to None, numpy scalars to Python numbers, tuples to lists."""
    if isinstance(obj, dict):
        return {str(k): json_ready(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [json_ready(v) for v in obj]
    if hasattr(obj, "item") and not isinstance(obj, bool | int | float | str):
        obj = obj.item()
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    return obj


def write_json(path: str | Path, payload: Any) -> Path:
    """Write ``payload`` as indented strict JSON, creating the folder."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(
        json.dumps(json_ready(payload), indent=2, allow_nan=False) + "\n", encoding="utf-8"
    )
    return p
