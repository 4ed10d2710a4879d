"""What each identification warning means and what to do, one line each.

Every warning the methods put in a result's ``warnings`` starts with its
kind, then a colon (``"residual test failed: ..."``; a trajectory's check of
its final estimate adds ``"final estimate: "`` in front). :data:`ADVICE`
declares each kind once with the line a student reads beside it, so the
command line, the server and the browser explain a warning the same way.
The module imports nothing heavy.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

from .notes import FINAL

__all__ = ["ADVICE", "advice", "warning_kind"]

#: The kind of a warning (its text before the first colon) -> what it means and what to do.
ADVICE: Mapping[str, str] = MappingProxyType(
    {
        "residual test failed": (
            "the model leaves structure in the errors, so it does not explain the record; "
            "compare with oe, give the dead time (--max-delay, --order) or a higher order"
        ),
        "implausible time constant": (
            "tau is outside what the record can show; record longer (several tau) or "
            "sample faster, and do not use this model"
        ),
        "implausible gain": (
            "the gain has the wrong sign for this plant; check the wiring and the columns "
            "of the record before trusting any result"
        ),
        "timing jitter": (
            "samples were not evenly spaced, which biases methods that assume one period; "
            "unload the machine or take a longer sample period, and re-record"
        ),
        "gap in time": (
            "samples are missing, so regressions across the gap mix unrelated samples; "
            "identify the part before or after the gap, or re-record"
        ),
        "estimates across a gap": (
            "these windows span missing samples and their estimates are wrong; read the "
            "estimates away from the gap"
        ),
        "operating point undetermined": (
            "the record cannot tell where the plant rests with the input off; give "
            "--offset initial (started at rest, input off) or --offset fit (started settled "
            "under the input or moving)"
        ),
        "constant term poorly determined": (
            "too few samples precede the input change to fix the ambient, so K and tau are "
            "uncertain; record longer before the step or give the ambient (--offset VOLTS)"
        ),
        "the optimiser did not converge": (
            "the output-error fit stopped early; its K, tau and dead time are not reliable: "
            "compare with lsm and check the record excites the plant"
        ),
        "no 63.2% crossing": (
            "the record ends before the response reached 63.2 %, so tau is extrapolated; "
            "record at least four time constants after the step"
        ),
        "small step": (
            "noise weighs more on a small step; use a step of at least the method's min_step"
        ),
        "short record": (
            "fewer samples than the paper's procedure asks for; record longer before "
            "trusting the figures"
        ),
        "moving before the step": (
            "the output was not at rest before the step, so the baseline is wrong; wait for "
            "the plant to settle, or use lsm or oe with --offset auto"
        ),
        "no sound fit": (
            "the few samples after the step do not determine K and tau; do not use them, "
            "and record at least four time constants after the step"
        ),
        "poor fit": (
            "the first-order response with these figures does not follow the record; "
            "check the record is one clean step from rest, or use lsm or oe"
        ),
        "not settled": (
            "the record ends before the output settles, so K and tau are extrapolated; "
            "record at least four time constants after the step"
        ),
        "final estimate not excited": (
            "the last estimate fits samples where nothing changes, so it follows the noise; "
            "give a longer window, an input that keeps changing, or use lsm or oe"
        ),
        "dead time ambiguous": (
            "several dead times fit the record as well, so the one chosen may be wrong; give "
            "the dead time or record a step the plant settles after"
        ),
    }
)


def warning_kind(warning: str) -> str:
    """The kind of ``warning``: its text before the first colon.

    Examples
    --------
    >>> warning_kind("final estimate: implausible gain: K = -1 has the wrong sign")
    'implausible gain'
    """
    text = warning[len(FINAL) :] if warning.startswith(FINAL) else warning
    return text.partition(":")[0].strip()


def advice(warning: str) -> str:
    """One line on what ``warning`` means and what to do.

    A warning of a kind not in :data:`ADVICE` gets a generic line (the
    warning's own text then says the rest).

    Examples
    --------
    >>> advice("timing jitter: the sample period spreads 12 % around its median")[:36]
    'samples were not evenly spaced, whic'
    >>> advice("something new: details")
    'the result may be wrong for the reason given; check the record before trusting it'
    """
    return ADVICE.get(
        warning_kind(warning),
        "the result may be wrong for the reason given; check the record before trusting it",
    )
