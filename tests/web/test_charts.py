"""The charts' redraw rate in a real browser: fast data draws REDRAWS_PER_SECOND times a second."""

from __future__ import annotations

from typing import Any

import pytest

pytestmark = pytest.mark.browser


def test_a_chart_fed_faster_than_its_redraw_rate_redraws_at_that_rate_and_shows_the_last_sample(
    module_page: Any,
) -> None:
    # A twin at the quick start's pace sends 60 samples/s: a phone following it redraws
    # ten times a second, and the last sample is on the chart once the data stop.
    r = module_page.evaluate(
        """async () => {
        const { Chart, REDRAWS_PER_SECOND } = await import('/js/charts.js');
        const x = [];
        const chart = new Chart(document.body, {
          label: 'T', xLabel: 't', yLabel: 'y', series: [{ label: 'y' }],
          source: () => [Float64Array.from(x), Float64Array.from(x)],
        });
        let draws = 0;
        const draw = chart.draw.bind(chart);
        chart.draw = () => { draws += 1; draw(); };
        const start = performance.now();
        while (performance.now() - start < 1000) {
          x.push(x.length);
          chart.invalidate();
          await new Promise((done) => setTimeout(done, 5));
        }
        await new Promise((done) => setTimeout(done, 400));
        const points = Number(chart.el.dataset.points);
        chart.destroy();
        return { draws, samples: x.length, points, rate: REDRAWS_PER_SECOND };
    }"""
    )
    assert r["samples"] >= 60, r  # the data came faster than the redraw rate
    assert 3 <= r["draws"] <= 15, r  # ten a second, for 1 s of data and the last redraw
    assert r["rate"] == 10
    assert r["points"] == r["samples"], r
