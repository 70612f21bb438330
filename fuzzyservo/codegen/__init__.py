"""Code generation: a fuzzy controller as self-contained C99 or IEC 61131-3 Structured Text,
and a rig's composed plant as C99 and an FMU (:func:`plant_fmu`).

The generated code computes the controller step exactly as the compiled evaluator does:
it embeds the packed parameter vector (:meth:`FuzzyController.pack`) and ports the
evaluator that reads it (:mod:`._c_runtime`, :mod:`._st`), so one evaluator exists in
three languages rather than a second design per target. No library, no allocation:
the state (previous error, previous command, scratch space) is a struct the caller owns.

``lut``: a lookup-table variant — the static map F sampled on an n (× n) grid over the
input universes (inputs are clipped to them, so the table covers every input) and
interpolated linearly (bilinearly); :func:`lut_error` measures how far it is from F.
"""

from fuzzyservo.codegen._c import c_sources, identifier, system_c_sources, write_c, write_st
from fuzzyservo.codegen._check import c_compiler, single_precision_error
from fuzzyservo.codegen._fmi import fmu_model, fmu_sources, model_description
from fuzzyservo.codegen._fmu import FmuBuild, fmi_headers, fmu_build
from fuzzyservo.codegen._lut import LutError, lut_error, lut_interp, lut_table
from fuzzyservo.codegen._plant_export import fmu_signals, plant_fmu, plant_fmu_model
from fuzzyservo.codegen._st_system import system_st_source
from fuzzyservo.plants.c_source import TranslationError, plant_c_sources

__all__ = [
    "FmuBuild",
    "LutError",
    "TranslationError",
    "c_compiler",
    "c_sources",
    "fmi_headers",
    "fmu_build",
    "fmu_model",
    "fmu_signals",
    "fmu_sources",
    "identifier",
    "lut_error",
    "lut_interp",
    "lut_table",
    "model_description",
    "plant_c_sources",
    "plant_fmu",
    "plant_fmu_model",
    "single_precision_error",
    "system_c_sources",
    "system_st_source",
    "write_c",
    "write_st",
]  # fmt: skip
