"""The closed loop's sentences in the reader's language (issue #24).

:data:`thermolab.control.words.LOOP_WORDS` declares, by stable code, every
sentence the tuning table's refused rows and a prediction's notes can say;
the API sends the code and its values beside the English. js/loopwords.js
names each code's catalogue sentence: the list is kept equal to the
declaration, and every language says each sentence with the same values.
"""

from __future__ import annotations

import re
import string
import sys
from pathlib import Path

import numpy as np

from thermolab.control import FOPDT, LOOP_WORDS, StepMetrics, settling_warning, settling_word
from thermolab.lab.runs.tuning_table import closed_loop_figures, tuning_table
from thermolab.web import STATIC_DIR

sys.path.insert(0, str(Path(__file__).parent))
from test_messages import TRANSLATIONS, catalogue, placeholders

MODULE = (STATIC_DIR / "js" / "loopwords.js").read_text(encoding="utf-8")
KEYS = dict(re.findall(r'\{ code: "([\w.]+)", key: "(loopWord\.\w+)" \}', MODULE))


def fields(template: str) -> set[str]:
    """The names a server sentence fills in."""
    return {name for _, name, _, _ in string.Formatter().parse(template) if name}


def test_every_code_the_server_declares_and_no_other_is_named() -> None:
    assert sorted(KEYS) == sorted(LOOP_WORDS)
    assert len(set(KEYS.values())) == len(KEYS)
    in_catalogue = {k for k in catalogue() if k.startswith("loopWord.")}
    assert in_catalogue == set(KEYS.values())


def test_every_language_says_each_sentence_with_the_servers_values() -> None:
    english = catalogue()
    for language in ("en", *TRANSLATIONS):
        messages = catalogue(language)
        for code, key in KEYS.items():
            text = messages.get(key)
            assert isinstance(text, str), (language, key)
            assert text, (language, key)
            assert placeholders(text) == fields(LOOP_WORDS[code]), (language, key)
            if language != "en":
                assert text != english[key], (language, key)  # said, not copied


def test_a_rule_that_cannot_tune_says_why_by_code_beside_its_english() -> None:
    table = tuning_table(
        FOPDT(0.14, 50.0, 0.0), dt=1.0, y0=0.0, u0=0.0, setpoint=0.7, u_limits=(-10.0, 10.0)
    )
    refused = {f"{r['rule']}-{r['form']}": r for r in table["rows"] if "error" in r}
    assert sorted(refused) == ["cc-pi", "cc-pid", "zn-pi", "zn-pid"]
    zn = refused["zn-pi"]
    assert zn["why"] == {"code": "needs_dead_time", "params": {"rule": "zn"}}
    # The English the command line and API clients read is unchanged.
    assert zn["error"] == (
        "rule 'zn' needs a dead time theta > 0; use imc or simc for a model without"
    )
    # Gains out of range: which gain, its value and its range (a dead time of a nanosecond).
    table = tuning_table(
        FOPDT(0.14, 50.0, 1e-9), dt=1.0, y0=0.0, u0=0.0, setpoint=0.7, u_limits=(-10.0, 10.0)
    )
    why = table["rows"][0]["why"]
    assert why["code"] == "gain_size_out_of_range"
    assert why["params"]["gain"] == "kp"
    assert (why["params"]["low"], why["params"]["high"]) == (1e-6, 1e4)
    assert why["params"]["value"] > 1e4
    assert table["rows"][0]["error"].startswith("kp must be finite with |kp| in [1e-06, 10000]")


def test_a_predictions_notes_come_by_code_beside_the_english_note() -> None:
    near = StepMetrics(1.7, 98.0, 1294.0, 0.0, 24.0, 0.02)
    far = StepMetrics(3.4, 139.0, 1250.0, 0.0, 24.0, 0.02)
    word = settling_word(near, far)
    assert word is not None
    assert word.to_dict() == {
        "code": "settling_near_band",
        "params": {"measured": 1.7, "predicted": 3.4, "band": 2.0},
    }
    assert word.text == settling_warning(near, far)
    # A run started without its model: the note and its code.
    t = np.arange(60.0)
    r = np.where(t >= 10, 1.0, 0.0)
    y = np.where(t >= 10, 1.0 - np.exp(-(t - 10) / 5.0), 0.0)
    samples = {"t": t.tolist(), "y": y.tolist(), "u": r.tolist(), "r": r.tolist()}
    control = {"kp": 1.0, "ti": 10.0}
    figures = closed_loop_figures(samples, 1.0, control, (0.0, 10.0), 0.0)
    assert figures["note"] == "the run was started without the model its gains came from"
    assert figures["notes"] == [{"code": "no_model", "params": {}}]
    figures = closed_loop_figures({**samples, "r": None}, 1.0, control, (0.0, 10.0), 0.0)
    assert figures["notes"] == [{"code": "no_setpoint_recorded", "params": {}}]
    flat = {**samples, "r": [0.0] * 60, "y": [0.0] * 60}
    figures = closed_loop_figures(flat, 1.0, control, (0.0, 10.0), 0.0)
    assert figures["notes"] == [{"code": "no_measured_step", "params": {}}]
    assert figures["note"].startswith("no set-point step to measure")
