"""The warning every identification method raises for a less trustworthy result."""

from __future__ import annotations

__all__ = ["IdentificationWarning"]


class IdentificationWarning(UserWarning):
    """A result was computed but is less trustworthy than usual.

    Raised as a warning (never an exception) by the identification methods: a
    record that has not settled, a step under 1 V, too few samples. The same
    text is kept in the result's ``warnings``, so a program that silences
    warnings can still show them.

    Examples
    --------
    >>> import warnings
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     warnings.warn("small step", IdentificationWarning, stacklevel=1)
    >>> caught[0].category.__name__
    'IdentificationWarning'
    """
