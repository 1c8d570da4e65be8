"""Exceptions raised by rsfcore, in one hierarchy.

::

    ValueError
     └── ParameterError              an input is outside its valid range (field, value, valid)
    RuntimeError
     └── UndecidedError              no certificate within the step budget (reason)
          ├── BudgetExceeded         ... because the step budget ran out (reason = "budget")
          └── IntegrationBudgetError a load-history segment needed more than its step budget

``ParameterError`` is a ``ValueError`` so that callers which validate generically keep
working; the application layer maps it to HTTP 422 / a CLI usage error naming ``field``
and ``valid``.  ``UndecidedError`` means "the numbers are fine but this run could not
finish": a larger budget may succeed (``reason == "budget"``) or not
(``reason == "step_underflow"``; ``reason == "not_certified"``: runs at tolerances 10x apart,
down to the tightest, disagree on the outcome, so the start lies within the integration's
error of the separatrix).

The classes were first defined in rsfcore.params, rsfcore.trajectory and
rsfcore.protocols; those modules re-export them, so old import paths keep working.
"""

from __future__ import annotations

__all__ = [
    "ParameterError",
    "UndecidedError",
    "BudgetExceeded",
    "IntegrationBudgetError",
]


class ParameterError(ValueError):
    """An input is outside its valid range. ``field`` names it, ``valid`` states the range."""

    def __init__(self, field: str, value: object, valid: str) -> None:
        self.field = field
        self.value = value
        self.valid = valid
        super().__init__(f"{field}={value!r} is invalid: valid range is {valid}")


class UndecidedError(RuntimeError):
    """The integration could not certify an outcome within its budget.

    ``reason`` is "budget" when the step budget ran out (a larger ``max_steps`` may
    succeed), "step_underflow" when the steps failed down to zero, or "not_certified"
    when runs at tolerances 10x apart (down to the tightest) disagree on the outcome.
    """

    def __init__(self, message: str, reason: str = "budget") -> None:
        super().__init__(message)
        self.reason = reason


class BudgetExceeded(UndecidedError):
    """The step budget ran out before a certificate (``reason`` is always "budget")."""

    def __init__(self, message: str) -> None:
        super().__init__(message, reason="budget")


class IntegrationBudgetError(BudgetExceeded):
    """A load-history segment needed more than its step budget (no runaway was certified)."""
