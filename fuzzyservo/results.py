"""What every result object shares: strict JSON text from ``to_dict()``, and ``str()``
from ``text()`` (the lines the command line prints)."""

from __future__ import annotations

import json
import math
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


class Result:
    """Base of the result objects the public functions return (no fields of its own)."""

    def to_dict(self) -> dict[str, Any]:
        raise NotImplementedError

    def text(self) -> str:
        raise NotImplementedError

    def to_json(self) -> str:
        """``to_dict()`` as indented strict JSON (NaN and inf are null)."""
        return json.dumps(json_ready(self.to_dict()), indent=2, allow_nan=False)

    def __str__(self) -> str:
        return self.text()
