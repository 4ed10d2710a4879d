"""The identification library's sentences, each declared once: its code and its English.

A method's warning, or the reason an estimate has no model, is one sentence,
"kind: detail" (the kind is what :data:`thermolab.ident.advice.ADVICE` explains).
The methods write it with :func:`note` from a template of :data:`NOTES`; the
results keep the English text (the library's, the command line's and the
stored runs' language).

The browser shows each sentence in the reader's language: it reads the code and
the figures back from the English with the patterns derived here
(:func:`read_note`), and fills the code's template of its own catalogue. Those
patterns reach it as ``web/static/js/identnotes.js``, written from them by
``python -m thermolab.web.identnotes`` (a test keeps it current), so a
sentence is declared here alone.

A figure in volts is written ``{name} V``: a record in other units has its
numbers' units rewritten (:func:`thermolab.ident.units.in_units`), so the
pattern reads the figure with whatever unit follows it.
"""

from __future__ import annotations

import re
import string
from collections.abc import Mapping
from functools import cache
from types import MappingProxyType

__all__ = ["FINAL", "NOTES", "note", "note_pattern", "read_note", "template_pattern"]

_RESIDUAL_CROSS = (
    "residual test failed: input-residual cross-correlation outside the 99 % bound ±{bound:.3g}; "
    "likely cause: "
)
_OP_GIVE = (
    "Give offset='initial' if the record starts at rest with the input off, offset='fit' if it "
    "starts settled under an input"
)

#: Every sentence of the methods, by code: its English template (``str.format``).
NOTES: Mapping[str, str] = MappingProxyType(
    {
        # Residual tests (ident/diagnostics.py for least squares, ident/oe.py for the OE fit).
        "residual_dead_time": _RESIDUAL_CROSS
        + "an input effect is left in the residuals at short lags: dead time",
        "residual_higher_order": _RESIDUAL_CROSS
        + "an input effect is left in the residuals: higher order or dead time "
        "(try order (2, 2, delay))",
        "residual_not_white": (
            "residual test failed: the residuals are not white (autocorrelation outside the "
            "99 % bound ±{bound:.3g}); likely cause: measurement noise, which biases an "
            "equation-error (ARX) fit towards a faster, smaller-gain model; compare with the "
            "output-error fit (thermolab.ident.output_error, method oe), or a drifting offset"
        ),
        "oe_residual_input": _RESIDUAL_CROSS
        + "the plant is not first order plus dead time (higher order) or the dead time is "
        "outside the range searched",
        "oe_residual_not_white": (
            "residual test failed: the simulation errors are not white (outside the 99 % bound "
            "±{bound:.3g}); likely cause: a slow drift of the ambient or a disturbance (coloured "
            "noise); the estimate is still unbiased for white noise"
        ),
        # Plausibility (ident/diagnostics.py).
        "tau_under_two_periods": (
            "implausible time constant: tau = {tau:.3g} s is under two sample periods "
            "(2 × {dt:g} s), too fast for the samples to show; the estimate is noise or the "
            "sampling is too slow"
        ),
        "tau_over_ten_records": (
            "implausible time constant: tau = {tau:.4g} s is more than ten times the record "
            "({duration:.4g} s); the record cannot determine it: record longer or excite more"
        ),
        "gain_not_positive": (
            "implausible gain: K = {K:.4g} has the wrong sign (expected positive); check the "
            "wiring, the operating point (offset) or the input's units"
        ),
        "gain_not_negative": (
            "implausible gain: K = {K:.4g} has the wrong sign (expected negative); check the "
            "wiring, the operating point (offset) or the input's units"
        ),
        # The time axis (ident/diagnostics.py, ident/_trust.py).
        "timing_jitter": (
            "timing jitter: the sample period spreads {spread:.1f} % around its median "
            "{median:.4g} s (over {limit:.0f} %), which biases methods that assume a fixed "
            "period; the real period is not dt"
        ),
        "time_gaps": (
            "gap in time: gaps in the record: {count} (the first after t = {first:.6g} s; about "
            "{missing} missing samples in all); windows and regressions across a gap mix samples "
            "that are not one period apart: cut the record at the gap"
        ),
        "windows_across_gap": (
            "estimates across a gap: the {window}-sample windows ending at samples {first} to "
            "{last} hold samples on both sides of the gap after t = {at:.6g} s, so they regress "
            "samples that are not one period apart; do not trust them"
        ),
        # The output-error fit (ident/oe.py); the optimiser's own message stays English.
        "optimiser_stopped": "the optimiser did not converge: {message}",
        # The operating point (ident/operating_point.py).
        "start_ambiguous": (
            "operating point undetermined: the ambient estimated free of the noise bias "
            "({ambient:.4g} ± {stderr:.2g} V) fits both a start at rest at y[0] and one settled "
            "under {u0:.4g} V; assumed offset='fit'. " + _OP_GIVE + ", or the known ambient in "
            "volts; better, record with the input off before the experiment"
        ),
        "start_too_early_fit": (
            "operating point undetermined: the input changes at sample {change}, too early "
            "to tell a start at ambient from one settled under {u0:.4g} V; assumed "
            "offset='fit'. " + _OP_GIVE + " or moving, or the known ambient in volts; better, "
            "record at least {need} samples before the step"
        ),
        "start_too_early_initial": (
            "operating point undetermined: the input changes at sample {change}; the "
            "constant term ({ambient:.4g} ± {stderr:.2g} V) cannot say whether the record starts "
            "at rest, so it is taken to (offset='initial'). If it was still moving, give "
            "offset='fit' and record at least {need} samples before the step"
        ),
        "constant_uncertain": (
            "constant term poorly determined: the ambient is {ambient:.4g} ± {stderr:.2g} V with "
            "the input changing at sample {change}, so K and tau are uncertain too; record "
            "at least {need} samples before the step, or give the known ambient in volts as "
            "offset"
        ),
        # The step method (ident/step.py).
        "no_crossing": (
            "no 63.2% crossing: the record ends before the output covers 63.2 % of its "
            "extrapolated change, so tau is the fitted time constant; record at least "
            "{settle:g} time constants after the step"
        ),
        "no_sound_fit": (
            "no sound fit: the {after} samples after the step give K = {K:.3g} and "
            "tau = {tau:.3g} s, which no first-order response has; do not use them, and record "
            "the whole response (at least four time constants) after the step"
        ),
        "not_settled": (
            "not settled: the record lasts {recorded:.2f} time constants after the step (needs "
            "{settle:g}); the last sample is {off:+.2f} % off the extrapolated gain; record at "
            "least {need} samples after the step"
        ),
        "not_settled_far": (
            "not settled: the record lasts {recorded:.2f} time constants after the step (needs "
            "{settle:g}); the last sample is {off:+.2f} % off the extrapolated gain; record many "
            "more samples after the step"
        ),
        "small_step": (
            "small step: the input changes by {amplitude:.3g} V, under {minimum:g} V, so noise "
            "weighs more on the result; use a step of at least {minimum:g} V"
        ),
        "short_record": (
            "short record: {n} samples, fewer than the {needed} the paper asks for (the "
            "transient and the settled output must both be recorded)"
        ),
        "moving_before_step": (
            "moving before the step: the output changed by {drift:.3g} V before the step "
            "({share:.0f} % of the response), so the baseline is uncertain; start from rest "
            "(a cold rig)"
        ),
        "poor_fit": (
            "poor fit: the first-order response with these K and tau misses the record by "
            "{rms:.3g} V RMS ({share:.0f} % of the change), so they do not describe it; record "
            "a clean step from rest and at least four time constants after it"
        ),
        "poor_fit_far": (
            "poor fit: the first-order response with these K and tau misses the record by "
            "{rms:.3g} V RMS (many times the change), so they do not describe it; record a "
            "clean step from rest and at least four time constants after it"
        ),
        # A trajectory's last estimate (ident/_trust.py).
        "final_not_excited": (
            "final estimate not excited: its last {span} samples hold the input constant and "
            "the output settled (within 10 times its noise), so it fits noise; {span} samples "
            "on a step see too little of the response to fit tau: give a longer window or block "
            "(or a smaller forgetting), an input that keeps changing, or use lsm or oe for a "
            "single step"
        ),
        "final_not_excited_since": (
            "final estimate not excited: its last {span} samples hold the input constant and "
            "the output settled (within 10 times its noise), so it fits noise (the last excited "
            "one ends near sample {excited}); {span} samples on a step see too little of "
            "the response to fit tau: give a longer window or block (or a smaller forgetting), "
            "an input that keeps changing, or use lsm or oe for a single step"
        ),
        # The dead-time search (ident/deadtime.py).
        "delay_ambiguous_repeats": (
            "dead time ambiguous: a delay of {delay} samples and of {others} samples fit the "
            "record equally well (the input repeats every {repeat} samples); give the dead time "
            "(order 1,1,DELAY) or record a step the plant settles after"
        ),
        "delay_ambiguous": (
            "dead time ambiguous: a delay of {delay} samples and of {others} samples fit the "
            "record equally well (the input does not excite the record enough to tell them "
            "apart); give the dead time (order 1,1,DELAY) or record a step the plant settles "
            "after"
        ),
        # Why a trajectory's estimate has no model (ident/models.py INVALID_REASONS).
        "no_estimate_yet": "no estimate yet: not enough samples have arrived",
        "not_excited": (
            "not excited: the regressor matrix is singular (input held constant or output settled)"
        ),
        "unstable": (
            "unstable or integrating model: a pole on or outside the unit circle (a >= 1), so "
            "there is no time constant"
        ),
        "non_positive_pole": (
            "dominant pole <= 0: a sampled first-order lag has 0 < a < 1, so there is no time "
            "constant"
        ),
        "complex_pole": (
            "dominant pole is complex: the model oscillates and has no first-order time constant"
        ),
        "non_finite": "non-finite estimate: the parameters overflowed or diverged",
        # Why a method gave no model at all (its error, kept as the run's reason).
        "too_few_after_step": (
            "too few samples after the step: the step is at sample {step} and only {after} "
            "samples follow; the step method needs at least {needed} (the paper records 2000)"
        ),
        # The record's screening before any method (ident/verdict.py, ident/_step_detect.py).
        "too_few_to_identify": (
            "too few samples: {n}, at least {needed} are needed to identify a model"
        ),
        "input_never_changes": (
            "no excitation: the input never changes (it stays at {u:g}), so no method can tell "
            "the gain from the ambient; record a step or a square wave"
        ),
        "no_step": (
            "no step: the input stays at {u:.6g} V for the whole record, so the output shows no "
            "step response"
        ),
        "no_step_first_sample": (
            "no step: the input stays at {u:.6g} V for the whole record, so the output shows no "
            "step response; if the step happened at the first sample, give u_initial (the input "
            "before it)"
        ),
        # Why an estimate is not trusted (ident/verdict.py): said whole, kind included.
        "no_model": "no model: {reason}",
        "poor_free_run_fit": (
            "poor free-run fit: the model's simulation follows the record to {fit:.1f} % "
            "(at least {minimum:g} % asked)"
        ),
        "poor_prediction": (
            "poor prediction: the model fitted on the first two thirds predicts the last "
            "third to {fit:.1f} % (at least {minimum:g} % asked)"
        ),
        "peer_gave_no_model": "no independent estimate to agree with ({method} gave no model)",
        "disagrees_with_peer": (
            "disagrees with {method} on the same record ({off}; more than {apart:g} % apart)"
        ),
        "dead_time_uncertain": (
            "dead time uncertain: {here:.3g} s here, {peer:.3g} s from {method} (more than "
            "{apart:g} s apart)"
        ),
        "start_uncertain": (
            "start uncertain: the input is on ({u0:g}) from the first row, and a kit at rest "
            "before the record gives K {K:.4g}, tau {tau:.4g} s instead; record some samples "
            "with the input off (or settled) first"
        ),
        "not_converged": (
            "the estimate did not converge: it never stays within ±1 % to the end of the record"
        ),
        "oe_no_excitation": (
            "no excitation: the input never changes in the record, so the output-error fit "
            "cannot tell the gain from the ambient; record a step or a square wave"
        ),
    }
)

#: The prefix of a trajectory's check of its last estimate ("final estimate: small step: ...").
FINAL = "final estimate: "
# In a template, a field followed by " V" is a figure in volts: in_units may rewrite that
# unit (or drop it), so its pattern takes the figure with whatever unit follows.
_VOLTS_AFTER = re.compile(r"^ V(?![A-Za-z])")
# in_units' other rewrites (units.py): "in volts" and "of volts".
_WORDS_REWRITTEN = {"in volts": "in the record's units", "of volts": ""}


def note(code: str, **values: object) -> str:
    """The sentence ``code`` of :data:`NOTES` with its figures.

    Examples
    --------
    >>> note("short_record", n=1500, needed=2000)[:59]
    'short record: 1500 samples, fewer than the 2000 the paper a'
    """
    return NOTES[code].format(**values)


def _escape(literal: str) -> str:
    """``literal`` as a pattern both Python's re and JavaScript's RegExp read alike."""
    escaped = re.sub(r"[.^$*+?()[\]{}|\\/]", lambda m: "\\" + m.group(), literal)
    for words, rewritten in _WORDS_REWRITTEN.items():
        escaped = escaped.replace(words, f"(?:{words}|{rewritten})")
    return escaped


@cache
def note_pattern(code: str) -> tuple[str, tuple[str, ...]]:
    """The pattern that reads sentence ``code`` back, and its groups' field names, in order.

    The groups are plain (not named), so that the same source is a JavaScript
    RegExp (flag ``s``). A field that comes twice is read at its first place.

    Examples
    --------
    >>> note_pattern("short_record")[1]
    ('n', 'needed')
    """
    return template_pattern(NOTES[code])


def template_pattern(template: str) -> tuple[str, tuple[str, ...]]:
    """The pattern that reads a sentence written from ``template`` back (any
    ``str.format`` template: :data:`NOTES`', the closed loop's words), and its groups'
    field names, in order; a figure's ``V`` after a field is read with whatever unit
    :func:`~thermolab.ident.units.in_units` gave it.

    Examples
    --------
    >>> template_pattern("rule {rule!r} needs theta > 0")
    ('^rule (.+?) needs theta > 0$', ('rule',))
    """
    parts = ["^"]
    names: list[str] = []
    after_field = False
    for literal, field, _spec, _conversion in string.Formatter().parse(template):
        if after_field and _VOLTS_AFTER.match(literal):
            literal = literal[2:]  # the figure's group takes its unit, whichever it is
        parts.append(_escape(literal))
        after_field = field is not None
        if field is None:
            continue
        if field in names:
            parts.append("(?:.+?)")
        else:
            parts.append("(.+?)")
            names.append(field)
    return "".join(parts) + "$", tuple(names)


def read_note(text: str) -> tuple[str, dict[str, str], bool] | None:
    """The code, the figures (as written) and whether it is a final estimate's, of ``text``.

    None for a sentence of no code (a newer method's, or one written by hand).

    Examples
    --------
    >>> read_note("final estimate: implausible gain: K = -0.1 has the wrong sign "
    ...           "(expected positive); check the wiring, the operating point (offset) or "
    ...           "the input's units")
    ('gain_not_positive', {'K': '-0.1'}, True)
    >>> read_note("small step: the input changes by 0.5 %, under 1 %, so noise weighs more "
    ...           "on the result; use a step of at least 1 %")
    ('small_step', {'amplitude': '0.5 %', 'minimum': '1 %'}, False)
    """
    final = text.startswith(FINAL)
    body = text[len(FINAL) :] if final else text
    for code in NOTES:
        source, names = note_pattern(code)
        found = re.match(source, body, re.DOTALL)
        if found:
            return code, dict(zip(names, found.groups(), strict=True)), final
    return None
