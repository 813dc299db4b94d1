"""Table 3 over several families and morphologies: the robust row first, the families, morphologies and price of
robustness named, one range spelling shared with the summary sentence and the survey row."""

import numpy as np
import pytest

from spiralbayes.inference.limits import compute_limits
from spiralbayes.inference.limits.table3 import build_table3, families_text, markdown_table, price_text, write_table
from spiralbayes.inference.limits.wording import format_range, format_ranges
from tests.inference.limits.test_robust import multi_family_scan

A_UP = {"compromise": (2.0, 0.5, 0.1), "hydro": (2.0, 2.0, 0.5)}  # hydro rules out only 3 M_th


@pytest.fixture(scope="module")
def limits():
    return compute_limits(multi_family_scan(variants=("compromise", "hydro"), a_up=A_UP))


def test_robust_row_first_names_its_families_morphologies_and_price(limits):
    table = build_table3(limits, name="two morphologies")
    assert len(table) == 1 + 6
    robust = table[0]
    assert robust["families"] == "all 6 families (each must rule it out): tau0 0.3; beta 10; h_p 0.05, 0.07, 0.1"
    assert robust["morphologies"] == "compromise, hydro"
    single = limits.m_lim[limits.family_index({"h_p": 0.07, "variant": "compromise"})]
    hydro = limits.m_lim[limits.family_index({"h_p": 0.07, "variant": "hydro"})]
    lo, hi = f"{np.min(hydro / single):.2g}", f"{np.max(hydro / single):.2g}"
    assert robust["price_of_robustness"] == (lo if lo == hi else f"{lo}-{hi}") == price_text(limits)
    assert float(lo) > 1  # the robust limit costs: hydro needs a heavier planet
    # 1 M_th: the compromise wake alone rules it out everywhere, the robust set nowhere
    assert robust["excluded_ge1Mth"] == "none"
    compromise_rows = [r for r in table[1:] if r["morphologies"] == "compromise"]
    assert len(compromise_rows) == 3 and all(r["excluded_ge1Mth"].startswith("14-42 au (") for r in compromise_rows)
    assert all(r["price_of_robustness"] == "" for r in table[1:])
    assert robust["excluded_ge3Mth"] == format_ranges(limits, [(0.1, 0.3)], 3.0)


def test_one_range_spelling_in_table_and_sentences(limits, tmp_path):
    text = format_range(limits, 0.1, 0.3, 3.0)
    masses = np.concatenate([limits.to_mjup(3.0, np.array([0.1, 0.3]), family=f) for f in limits.families])
    assert text == f"14-42 au ({np.min(masses):.2g}-{np.max(masses):.2g} M_Jup)"
    assert text in limits.summary() and text in markdown_table(build_table3(limits))
    fam = limits.families[0]
    one = format_range(limits, 0.1, 0.3, 3.0, fam)
    assert one in limits.summary(fam) and one != text  # one family's own h_p: a narrower M_Jup span
    ecsv, md = write_table(build_table3(limits, name="d"), tmp_path / "table3")
    assert ecsv.name == "table3.ecsv" and md.read_text().startswith("Exclusion limits for d: CL = 95%")


def test_a_single_family_is_its_own_robust_row():
    single = compute_limits(multi_family_scan(h_ps=(0.07,)))
    table = build_table3(single)
    assert len(table) == 1 and table[0]["families"] == families_text(single) == single.families[0].label
    assert table[0]["morphologies"] == "unlabelled" and table[0]["price_of_robustness"] == "1"  # no variant, not wake_
