"""The studies on the dashboard (SPEC §8) in a real headless Chromium, against a dask scheduler,
two workers and the API as separate processes: a sampled sweep's sensitivity bars and
reliability figure (re-drawn for another output and limit from the page's form), and a search
page that follows its trials live to the answer."""
from __future__ import annotations

import httpx
import pytest

from service.process import running_cluster, running_service
from service_helpers import THINNEST_SEARCH, sampled_sweep, wait_until
import test_dashboard
from test_dashboard import images_loaded, screenshot

pytestmark = pytest.mark.slow
browser = test_dashboard.browser  # the headless Chromium fixture

SAMPLED = sampled_sweep("ground uncertainty", 128, 2)
SEARCH = THINNEST_SEARCH


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    logs = tmp_path_factory.mktemp("logs")
    with running_cluster(2, logs=logs) as scheduler:
        with running_service(tmp_path_factory.mktemp("results"), scheduler=scheduler, log=logs / "api.log") as url:
            yield url


def test_sweep_analyses_and_a_live_search_page(service, browser, tmp_path):
    url = service
    sweep = httpx.post(f"{url}/sweeps", json=SAMPLED).json()
    wait_until(lambda: httpx.get(f"{url}/sweeps/{sweep['id']}").json()["counts"]["done"] == 128, timeout=180,
               what="the sampled sweep")
    browser.get(f"{url}/ui/sweeps/{sweep['id']}")
    wait_until(lambda: all(images_loaded(browser, "#analyses img")) and len(images_loaded(browser, "#analyses img"))
               == 2, timeout=60, what="the analyses' figures")
    screenshot(browser, tmp_path / "sweep-analyses.png")
    # another output and limit from the form: the figures follow
    browser.execute_script("document.getElementById('analysis-output').value = 'max_thrust';"
                           "document.getElementById('analysis-limit').value = '0.4';")
    browser.find_element("css selector", "#analysis-form button").click()
    def sources():  # read at once (the page is being replaced)
        return browser.execute_script(
            "return [...document.querySelectorAll('#analyses img')].map(i => i.getAttribute('src'))")

    wait_until(lambda: any("output=max_thrust" in src for src in sources()), timeout=30,
               what="the new sensitivity figure")
    assert any("limit=0.4" in src for src in sources())
    browser.execute_script("document.getElementById('analyses').scrollIntoView()")
    wait_until(lambda: all(images_loaded(browser, "#analyses img")), timeout=60, what="the new figures")
    screenshot(browser, tmp_path / "sweep-analyses-thrust.png")

    search = httpx.post(f"{url}/searches", json=SEARCH).json()
    browser.get(f"{url}/ui/searches/{search['id']}")

    def shown():  # read at once: the page swaps its parts as trials land
        return browser.execute_script(
            "const s = document.getElementById('search-status');"
            "return [s.dataset.status, document.getElementById('search-answer').textContent,"
            "        document.querySelectorAll('#trials-table tbody tr').length];")

    assert shown()[0] == "running"
    # the page follows the search by itself to its answer
    wait_until(lambda: shown()[0] == "done", timeout=180, what="the search page to show the answer")
    done = httpx.get(f"{url}/searches/{search['id']}", timeout=30).json()  # a loaded host: 5 s was missed once
    wait_until(lambda: shown()[2] == len(done["trials"]), timeout=30, what="every trial in the table")
    status, answer, rows = shown()
    assert f"geometry.thickness = {done['value']:.4g}" in answer and rows >= 3
    wait_until(lambda: all(images_loaded(browser, "img[data-plot=trials]")), timeout=30, what="the trials figure")
    screenshot(browser, tmp_path / "search.png")
    browser.get(url)
    assert browser.find_element("css selector", f"#searches tr[data-key='{search['id']}']")


def test_a_reliability_study_page_follows_the_study_to_its_answer(service, browser, tmp_path):
    """A FORM study posted to the service (exact β 2.0): its page shows the progress while it runs
    and, by itself, β with its interval, the design point and importance factors, the convergence
    figure and the design-point case, whose page opens."""
    from test_reliability_api import study_at

    url = service
    ident = httpx.post(f"{url}/reliability", json=study_at(2.0, 40, "page"), timeout=30).json()["id"]
    browser.get(f"{url}/ui/reliability/{ident}")

    def shown():
        return browser.execute_script(
            "const s = document.getElementById('reliability-status');"
            "return s ? [s.dataset.status, document.getElementById('reliability-answer').textContent,"
            "            document.querySelectorAll('#importance-table tbody tr').length] : [null, '', 0];")

    wait_until(lambda: shown()[0] == "done", timeout=240, what="the reliability page to show the answer")
    done = httpx.get(f"{url}/reliability/{ident}", timeout=30).json()
    status, answer, rows = shown()
    assert f"β = {done['beta']:.3f}" in answer and "95 %" in answer and f"{done['calls']} FE calls" in answer
    assert abs(done["beta"] - 2.0) < 0.02 and rows == 2
    wait_until(lambda: all(images_loaded(browser, "#reliability-convergence img")), timeout=60,
               what="the convergence figure")
    screenshot(browser, tmp_path / "reliability.png")
    browser.find_element("css selector", f"#reliability-design-point a[href='/ui/cases/{done['design_case']}']").click()
    wait_until(lambda: done["design_case"] in browser.current_url, timeout=30, what="the design-point case page")
    link = browser.find_element("css selector", f"#design-point-of a[href='/ui/reliability/{ident}']")
    assert "The design point of reliability study" in browser.find_element("id", "design-point-of").text
    link.click()
    wait_until(lambda: f"/ui/reliability/{ident}" in browser.current_url, timeout=30, what="back to the study")
