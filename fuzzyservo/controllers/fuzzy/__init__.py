"""Mamdani fuzzy controllers: the system, the seven-term design, the compiled evaluator.

scikit-fuzzy defines the semantics (:mod:`.skfuzzy_adapter`, the only module that
imports ``skfuzzy.control``); :mod:`.evaluate` reproduces it in compiled code.
"""

from fuzzyservo.controllers.fuzzy.controller import FORMS, FuzzyController
from fuzzyservo.controllers.fuzzy.design import (
    SEVEN_TERMS,
    SevenTermDesign,
    identity_rules,
    macvicar_whelan,
)
from fuzzyservo.controllers.fuzzy.system import FuzzySystem, Rule, Term, Variable

__all__ = [
    "FORMS",
    "SEVEN_TERMS",
    "FuzzyController",
    "FuzzySystem",
    "Rule",
    "SevenTermDesign",
    "Term",
    "Variable",
    "identity_rules",
    "macvicar_whelan",
]
