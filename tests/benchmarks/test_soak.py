"""soak.py's figures from its samples: RSS growth per sim hour after the warm-up (a fitted line, in
MB and in % of the RSS the warm-up ended with), descriptor growth and CPU share."""
from __future__ import annotations

import pytest


def test_growth_fits_the_samples_after_the_warm_up(load_benchmark) -> None:
    soak = load_benchmark("soak")
    ticks = soak.TICKS
    samples = []
    for minute in range(0, 61, 5):
        # 100 MB growing 10 MB per sim hour after a warm-up of 10 min that doubled it from 50 MB;
        # a descriptor leaked every 20 min; half a core (the wall runs at 2x: 30 wall s per sim minute).
        rss = 50.0 + 5.0 * minute if minute <= 10 else 100.0 + 10.0 * (minute - 10) / 60
        samples.append((minute * 60.0, minute * 30.0, {"navigation": {
            "rss_mb": rss, "cpu_ticks": 0.5 * ticks * minute * 30.0, "fds": 18 + minute // 20}}))
    (name, figures), = soak.growth(samples, warmup_s=600.0).items()
    assert name == "navigation"
    assert figures["rss_mb_at_warmup"] == 100.0 and figures["rss_growth_mb_per_sim_hour"] == pytest.approx(10.0)
    assert figures["rss_growth_pct_per_sim_hour"] == pytest.approx(10.0)
    assert figures["fd_growth"] == 3 - 0 and figures["cpu_pct"] == pytest.approx(50.0)
    with pytest.raises(SystemExit, match="only 2 samples after the warm-up"):
        soak.growth(samples[:3], warmup_s=300.0)
