"""Runs, signals and numbers written for people, in each language (js/runwords.js,
js/quantities.js, model.js's figures), run in a real Chromium without a lab.

What a new teacher met on Brazilian pages: "step:0:10@1" as a run's input,
"concluído (completed)", "dt = 1, samples = 2000", "ambiente 2,29665e-26",
deviations as "-3,062e-9", "1 a 9007199254740992" as a range.
"""

from __future__ import annotations

from typing import Any

import pytest

pytestmark = pytest.mark.browser

WORDS = """
const i18n = await import('/js/i18n.js');
const words = await import('/js/runwords.js');
const { formatQuantity, quantityOfUnit, unitSymbol } = await import('/js/quantities.js');
const { channelLabel } = await import('/js/channelwords.js');
const { fmtFigure, fmtDeviation, fmtPercentDeviation } = await import('/js/model.js');
const { rangeText } = await import('/js/validate.js');
const { rigTitle } = await import('/js/shapes.js');
await i18n.useLanguage(arg);
const reason = (r) => { const w = words.endReasonText(r); return w && [w.text, w.detail]; };
return {
  step: words.signalText('step:0:10@1'),
  square: words.signalText('square:4:6:0.1'),
  automatic: words.signalText('square:0:4:0.1000000000001'),
  sine: words.signalText('sine:5:1:0.05'),
  prbs: words.signalText('prbs:0:4:5:0'),
  constant: words.signalText('const:2.5'),
  unknown: words.signalText('chirp:1:2'),
  manual: words.inputText({ signal: null, setpoint: 2.5 }),
  raw: words.inputText({ signal: 'chirp:1:2', setpoint: null }),
  completed: reason('completed'),
  endedBy: reason('ended by ana'),
  interlock: reason('interlock: output 11.2 V over the limit 11 V'),
  stopped: reason('the server stopped during the run'),
  linkLost: reason('link_lost: link to the lab lost for over 30 s'),
  hostAway: reason('host_away: offline (not connected)'),
  ownerGone: reason('owner_gone: no lab worker owned the rigs for over 30 s'),
  other: reason('something new'),
  settings: words.settingsText({ dt: 1, samples: 2000, signal: 'step:0:10@1', offset: 'auto',
                                 window: 100, gamma: 0.96, block: 0, methods: ['lsm'] }),
  ambient: formatQuantity(2.29665e-26, 'volts'),
  noise: formatQuantity(250.12623300000004, 'seconds'),
  negative: formatQuantity(-0.0001, 'volts'),
  // A kit's channels by their declared units: sensor 2 read with float noise, heater 2.
  channels: [formatQuantity(31.259999999999998, quantityOfUnit('degC')),
             formatQuantity(40.00000000001, quantityOfUnit('%')),
             formatQuantity(1.23456, quantityOfUnit('mA')), unitSymbol('degC'), unitSymbol('V')],
  labels: [channelLabel('t2', 'degC'), channelLabel('q2', '%'), channelLabel('x9', '')],
  figures: [fmtFigure(6.6293e-11), fmtFigure(250.12623300000004), fmtFigure(0.1400901)],
  deviations: [fmtDeviation(-3.062e-9), fmtDeviation(0.0021), fmtDeviation(-0.5)],
  percents: [fmtPercentDeviation(-2.2e-11), fmtPercentDeviation(-0.01254)],
  range: rangeText({ label: 'run', min: 1, max: 2 ** 53, integer: true }),
  rig: rigTitle({ id: 'twin', title: "Digital twin of the paper's box" }),
  ownRig: rigTitle({ id: 'lab2', title: 'Sala 2.14' }),
};
"""


def words(page: Any, language: str) -> dict[str, Any]:
    return dict(page.evaluate(f"async (arg) => {{ {WORDS} }}", language))


def test_a_run_is_described_in_brazilian_portuguese(module_page: Any) -> None:
    r = words(module_page, "pt-BR")
    assert r["step"] == "degrau de 0 a 10 V em t = 1 s"
    assert r["square"] == "onda quadrada entre 4 e 6 V, período de 10 s"
    assert r["automatic"] == "onda quadrada entre 0 e 4 V, período de 10 s"
    assert r["sine"] == "senoide em torno de 5 V, amplitude de 1 V, período de 20 s"
    assert r["prbs"] == "sequência binária pseudoaleatória entre 0 e 4 V, bits de 5 s"
    assert r["constant"] == "constante em 2,5 V"
    assert r["unknown"] is None
    assert r["raw"] == "chirp:1:2"  # a form this page does not know is shown as sent
    assert r["manual"] == "entrada de 2,5 V (manual)"
    assert r["completed"] is None  # "concluído" says it all
    assert r["endedBy"] == ["encerrado por ana", None]
    assert r["interlock"] == ["um limite de segurança atuou", "output 11.2 V over the limit 11 V"]
    assert r["stopped"] == ["o servidor do laboratório parou durante o ensaio", None]
    assert r["other"] == ["", "something new"]
    # A rig host's run ended for want of the lab: its real cause, in the reader's words.
    assert r["linkLost"] == [
        "o computador da bancada perdeu a conexão com o laboratório por mais tempo que a"
        " tolerância",
        "link to the lab lost for over 30 s",
    ]
    assert r["hostAway"] == [
        "o computador da bancada ficou ausente por mais tempo que a tolerância",
        "offline (not connected)",
    ]
    assert r["ownerGone"] == [
        "o servidor do laboratório que controlava a bancada parou e nenhum outro assumiu a tempo",
        "no lab worker owned the rigs for over 30 s",
    ]
    assert r["settings"] == [
        "Janela (amostras): 100",
        "Fator de esquecimento γ: 0,96",
        "LSM a cada N amostras: só ao ENCERRAR",
    ]
    assert r["ambient"] == "0"
    assert r["noise"] == "250,126"
    assert r["negative"] == "0"
    assert r["channels"] == ["31,26", "40", "1,235", "°C", "V"]
    assert r["labels"] == ["Temperatura 2, T2 (°C)", "Aquecedor 2, Q2 (%)", "x9"]
    assert r["figures"] == ["0,000000", "250,126233", "0,140090"]
    assert r["deviations"] == ["0", "+0,0021", "−0,5"]
    assert r["percents"] == ["0 %", "−1,25 %"]
    assert r["range"] == "um inteiro no mínimo 1"
    assert r["rig"] == "Gêmeo digital da caixa do artigo"
    assert r["ownRig"] == "Sala 2.14"


def test_a_run_is_described_in_spanish_and_english(module_page: Any) -> None:
    es = words(module_page, "es")
    assert es["step"] == "escalón de 0 a 10 V en t = 1 s"
    assert es["endedBy"] == ["finalizado por ana", None]
    assert es["ownerGone"][0] == (
        "el servidor del laboratorio que controlaba el equipo se detuvo y ninguno lo reemplazó"
        " a tiempo"
    )
    assert es["deviations"] == ["0", "+0,0021", "−0,5"]
    en = words(module_page, "en")
    assert en["step"] == "step from 0 to 10 V at t = 1 s"
    assert en["square"] == "square wave between 4 and 6 V, period 10 s"
    assert en["manual"] == "input 2.5 V (manual)"
    assert en["noise"] == "250.126"
    assert en["labels"] == ["Temperature 2, T2 (°C)", "Heater 2, Q2 (%)", "x9"]
    assert en["figures"] == ["0.000000", "250.126233", "0.140090"]
    assert en["rig"] == "Digital twin of the paper's box"
    assert en["linkLost"][0] == "the rig's host lost its link to the lab for longer than its grace"
