"""The live-view benchmark's figures on constructed samples: the latency target is judged on one
browser open, after a page's first minute; samples with two browsers are reported apart."""
from __future__ import annotations

import argparse

import pytest


@pytest.fixture(scope="module")
def view_browser(load_benchmark):
    return load_benchmark("view_browser")


def test_latency_is_judged_on_one_browser_after_a_pages_first_minute(view_browser):
    first = view_browser.Watched("first", page=None, pid=0, opened_s=0.0, clicks_s=[1.0, 2.5])
    late = view_browser.Watched("late1", page=None, pid=0, opened_s=1200.0, clicks_s=[1.5])
    first.samples = [{"open_s": 0, "latency_s": 9.0, "memory_mb": 700.0, "browsers": 1},  # its start
                     {"open_s": 600, "latency_s": 1.2, "memory_mb": 1000.0, "browsers": 1},
                     {"open_s": 1260, "latency_s": 2.9, "memory_mb": 1010.0, "browsers": 2}]
    late.samples = [{"open_s": 5, "latency_s": 16.0, "memory_mb": 600.0, "browsers": 2},
                    {"open_s": 65, "latency_s": 3.1, "memory_mb": 740.0, "browsers": 2}]
    args = argparse.Namespace(world="cones")
    result = view_browser.figures([first, late], args, 1300.0, view_browser.Robot(radius_m=3.0, sim_s=1303.0))
    assert result["latency_s_max"] == 16.0 and result["latency_s_max_after_first_minute"] == 1.2
    assert result["latency_s_max_two_browsers"] == 3.1
    assert result["tab_mb_max"] == 1010.0 and result["click_to_goal_s_max"] == 2.5
    assert result["met"] == {"alive": True, "tab_mb": True, "latency_s": True, "click_to_goal_s": True}
    first.samples.append({"open_s": 1400, "latency_s": 2.2, "memory_mb": 1020.0, "browsers": 1})
    first.dead = "RuntimeError: unreachable"
    result = view_browser.figures([first, late], args, 1400.0, view_browser.Robot(radius_m=3.0))
    assert result["met"]["latency_s"] is False and result["met"]["alive"] is False
    assert result["deaths"] == {"first": "RuntimeError: unreachable"}
