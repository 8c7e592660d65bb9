"""The dashboard in a real headless Chromium, against the deployment's topology on loopback
(a dask scheduler, one worker and the API as separate processes).

Screenshots of every page are saved under the test's temporary directory.
"""
from __future__ import annotations

import csv
import io
import json
import shutil
import time
from pathlib import Path

import httpx
import pytest

from service.comparison import SCALAR_ORDER
from service.process import running_cluster, running_service
from service_helpers import wait_until
from workflows.plots import PLOTS
from workflows.result_store import as_store

selenium = pytest.importorskip("selenium", reason="selenium is in the 'test' extra")
from selenium import webdriver  # noqa: E402
from selenium.webdriver.chrome.service import Service  # noqa: E402
from selenium.webdriver.common.by import By  # noqa: E402

pytestmark = pytest.mark.slow

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
CHROMEDRIVER = shutil.which("chromedriver") or "/usr/bin/chromedriver"
#: Chromium on a closed network: no first-run work, no background fetches, no GPU.
CHROMIUM_FLAGS = ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--disable-dev-shm-usage", "--window-size=1400,1000")
#: Small cases that solve in about a second each.
SMALL = {"geometry": {"depth": 10.0, "width": 20.0, "height": 25.0},
         "mesh": {"interface_size": 0.2, "far_size": 8.0}}


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """A dask scheduler with one worker (so cases queue behind each other); yields its address."""
    with running_cluster(1, logs=tmp_path_factory.mktemp("cluster-logs")) as scheduler:
        yield scheduler


@pytest.fixture(scope="module")
def service(cluster, tmp_path_factory):
    """The API on a free port, on :func:`cluster`."""
    logs = tmp_path_factory.mktemp("logs")
    results = tmp_path_factory.mktemp("results")
    with running_service(results, scheduler=cluster, log=logs / "api.log") as url:
        yield url, results


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    if not (Path(CHROMIUM).exists() and Path(CHROMEDRIVER).exists()):
        pytest.fail("Chromium and its driver are missing: `make sysdeps` installs Debian's "
                    "chromium and chromium-driver")
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in CHROMIUM_FLAGS:
        options.add_argument(flag)
    options.add_argument(f"--user-data-dir={tmp_path_factory.mktemp('chromium-profile')}")
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    # a page's load waits for its figures, which the API renders on first request (a case page's eight
    # take some 5 s of CPU alone): on two cores shared with the rest of the suite that took over 30 s once
    driver.set_page_load_timeout(120)
    driver.set_script_timeout(30)
    try:
        yield driver
    finally:
        driver.quit()


def screenshot(driver, path: Path) -> Path:
    """The whole page as a PNG (the window grown to the page's height first)."""
    height = driver.execute_script("return document.documentElement.scrollHeight")
    driver.set_window_size(1400, min(max(height, 600), 6000) + 120)
    driver.save_screenshot(str(path))
    driver.set_window_size(1400, 1000)
    return path


def images_loaded(driver, selector: str) -> list[int]:
    """naturalWidth of every image matched (0 while loading or broken)."""
    return driver.execute_script(
        "return [...document.querySelectorAll(arguments[0])].map(i => i.complete ? i.naturalWidth : 0)", selector)


def state_shown(driver) -> tuple[str, str]:
    """The counts signature and the state badge of a sweep page (read at once: parts are swapped live)."""
    return tuple(driver.execute_script(
        "const s = document.getElementById('sweep-status');"
        "return [s.dataset.signature, s.querySelector('[data-field=state]').textContent];"))


def case_status_shown(driver) -> str:
    return driver.execute_script("return document.querySelector('#case-main h1 .badge').textContent")


def index_state_shown(driver, sweep_id: str) -> str:
    return driver.execute_script(
        "const row = document.querySelector(`#sweeps tr[data-key='${arguments[0]}']`);"
        "return row && row.querySelector('[data-field=state]').textContent", sweep_id)


def column(driver, name: str) -> list[str]:
    """The data-value of column ``name`` of the comparison table, in row order."""
    return driver.execute_script("""
        const table = document.getElementById('comparison-table');
        const index = [...table.tHead.rows[0].cells].findIndex(th => th.dataset.col === arguments[0]);
        return [...table.tBodies[0].rows].map(r => r.cells[index].dataset.value);""", name)


def test_submit_a_sweep_watch_it_sort_it_open_a_case_download_the_csv(service, browser, tmp_path):
    url, results = service
    browser.get(url + "/")
    assert "Sweeps" in browser.find_element(By.TAG_NAME, "h2").text
    screenshot(browser, tmp_path / "index-empty.png")
    # the test scheduler serves no dashboard (no bokeh, --no-dashboard): no dead link
    assert not browser.find_elements(By.ID, "dask-dashboard")

    # submit a 2 x 2 sweep through the form
    browser.find_element(By.LINK_TEXT, "Submit").click()
    sweep = {"name": "browser", "base": SMALL, "mode": "grid",
             "vary": {"lining.thickness": [0.2, 0.3], "ground.young": [2e7, 5e7]}}
    browser.find_element(By.CSS_SELECTOR, "input[name=kind][value=sweeps]").click()
    text = browser.find_element(By.ID, "body")
    text.clear()
    text.send_keys(json.dumps(sweep))
    browser.find_element(By.ID, "submit").click()
    wait_until(lambda: "/ui/sweeps/" in browser.current_url, timeout=20, what="the sweep page")
    sweep_id = browser.current_url.rsplit("/", 1)[1]
    record = httpx.get(f"{url}/sweeps/{sweep_id}").json()
    assert record["name"] == "browser" and record["total"] == 4

    # the status changes on this very page object: no reload
    browser.execute_script("window.__marker = 'same page'")
    first = state_shown(browser)[0]
    assert first.split(",")[2] != "4", "the sweep finished before its page was shown"
    seen = {first}

    def finished():
        signature, state = state_shown(browser)
        seen.add(signature)
        return state == "finished"
    wait_until(finished, timeout=60, interval=0.2, what="the page to show the sweep finished")
    assert browser.execute_script("return window.__marker") == "same page"
    assert len(seen) >= 2  # at least one intermediate state was shown, then the final one
    assert browser.find_element(By.ID, "sweep-status").get_attribute("data-signature") == "0,0,4,0,0"

    # the table: one row per case; varied parameters, then η, the status and the case, then the other results
    headers = [th.get_attribute("data-col") for th in browser.find_elements(By.CSS_SELECTOR, "#comparison-table th")]
    assert headers[:5] == ["lining_thickness", "ground_young", "max_utilization", "status", "case_id"]
    assert headers[5] == "max_contact_pressure"
    assert column(browser, "status") == ["done"] * 4
    k = headers.index("max_utilization")
    for tr in browser.find_elements(By.CSS_SELECTOR, "#comparison-table tbody tr"):
        td = tr.find_elements(By.TAG_NAME, "td")[k]
        value = float(td.get_attribute("data-value"))
        assert ("over" in td.get_attribute("class")) == (value > 1)  # red where the section fails

    # sort by a scalar, both ways
    browser.find_element(By.CSS_SELECTOR, "th[data-col=max_abs_moment]").click()
    ascending = [float(v) for v in column(browser, "max_abs_moment")]
    assert ascending == sorted(ascending) and len(set(ascending)) == 4
    assert browser.find_element(By.CSS_SELECTOR, "th[data-col=max_abs_moment]").get_attribute(
        "aria-sort") == "ascending"
    browser.find_element(By.CSS_SELECTOR, "th[data-col=max_abs_moment]").click()
    assert [float(v) for v in column(browser, "max_abs_moment")] == sorted(ascending, reverse=True)

    # the sweep plots
    wait_until(lambda: (w := images_loaded(browser, "#plots img")) and len(w) == 4 and all(w),
               timeout=60, what="the sweep plots to load")
    screenshot(browser, tmp_path / "sweep.png")

    # download the CSV through the page's link
    downloads = tmp_path / "downloads"
    downloads.mkdir()
    browser.execute_cdp_cmd("Page.setDownloadBehavior", {"behavior": "allow", "downloadPath": str(downloads)})
    browser.find_element(By.ID, "download-csv").click()
    csv_file = wait_until(lambda: next(downloads.glob("*.csv"), None), timeout=20, what="the CSV download")
    units, *rows = csv.DictReader(io.StringIO(csv_file.read_text()))  # a units row under the header
    assert [r["case_id"] for r in rows] == record["case_ids"]
    assert list(rows[0])[:4] == ["case_id", "status", "lining_thickness", "ground_young"]
    assert [c for c in list(rows[0])[4:] if c in SCALAR_ORDER] == [c for c in SCALAR_ORDER if c in rows[0]]
    assert (units["lining_thickness"], units["ground_young"], units["max_contact_pressure"],
            units["max_abs_moment"]) == ("m", "MPa", "kPa", "kN·m/m")
    assert {(float(r["lining_thickness"]), float(r["ground_young"])) for r in rows} == {
        (t, e) for t in (0.2, 0.3) for e in (20.0, 50.0)}
    for row in rows:
        summary = httpx.get(f"{url}/cases/{row['case_id']}").json()["summary"]
        assert row["status"] == "done"
        assert float(row["max_contact_pressure"]) == pytest.approx(summary["max_contact_pressure"] / 1e3, rel=1e-14)
        assert float(row["max_abs_moment"]) == pytest.approx(summary["max_abs_moment"] / 1e3, rel=1e-14)

    # a case page: summary, plots, downloads, its JSON
    first_case = browser.find_element(By.CSS_SELECTOR, "#comparison-table tbody tr a")
    case_id = first_case.text
    first_case.click()
    wait_until(lambda: browser.current_url.endswith(f"/ui/cases/{case_id}"), timeout=20, what="the case page")
    wait_until(lambda: (w := images_loaded(browser, ".plots img")) and len(w) == len(PLOTS) and all(w),
               timeout=60, what="the case plots to load")
    assert browser.find_element(By.ID, "summary").text.count("\n") >= 10
    assert browser.find_element(By.ID, "download-nc").get_attribute("href").endswith(f"/cases/{case_id}/result.nc")
    report = browser.find_element(By.ID, "download-report").get_attribute("href")
    assert report.endswith(f"/cases/{case_id}/report.pdf")
    assert httpx.get(report, timeout=120).content.startswith(b"%PDF")
    spec = json.loads(browser.find_element(By.ID, "case-json").text)
    assert spec["mesh"]["interface_size"] == 0.2
    # the design answer is stated: PASS or FAIL with the utilization, as the summary has it
    verdict = browser.find_element(By.ID, "design-verdict")
    word = verdict.find_element(By.TAG_NAME, "strong").text
    assert word in ("PASS", "FAIL") and "max utilization" in verdict.text
    cells = {td.find_element(By.XPATH, "following-sibling::td[2]").text: td for td in
             browser.find_elements(By.CSS_SELECTOR, "#summary td.num")}
    eta = float(cells["max_utilization"].get_attribute("data-value"))
    # and the shear and crack width checks (SPEC §9.3; the default crack width limit, 0.3 mm)
    shear, crack = (float(cells[n].get_attribute("data-value")) for n in ("max_shear_utilization", "max_crack_width"))
    assert word == ("PASS" if eta <= 1 and shear <= 1 and crack <= 0.3e-3 else "FAIL")
    assert "crack width" in verdict.text
    assert ("over" in cells["max_utilization"].get_attribute("class")) == (eta > 1)
    # the solver's diagnostics in their own table, not among the engineering results
    solver_rows = {td.find_element(By.XPATH, "following-sibling::td[2]").text for td in
                   browser.find_elements(By.CSS_SELECTOR, "#diagnostics td.num")}
    assert {"kkt_residual", "iterations", "solve_seconds"} <= solver_rows and not solver_rows & set(cells)
    screenshot(browser, tmp_path / "case.png")

    browser.get(url + "/")
    assert sweep_id in browser.find_element(By.ID, "sweeps").text
    assert case_id in browser.find_element(By.ID, "cases").text
    # the recent cases show each case's utilization, red above 1
    row = browser.find_element(By.CSS_SELECTOR, f"#cases tr[data-key='{case_id}']")
    eta_cell = row.find_element(By.CSS_SELECTOR, "td[data-field='summary.max_utilization']")
    assert eta_cell.text and ("over" in eta_cell.get_attribute("class")) == (float(eta_cell.text) > 1)
    assert float(eta_cell.text) == pytest.approx(eta, rel=1e-2)
    screenshot(browser, tmp_path / "index.png")
    print(f"screenshots in {tmp_path}")


#: Coarse cases, two of them loaded far beyond small displacements (solved, with warnings).
WARNED_SWEEP = {"name": "warned rows", "base": {"mesh": {"interface_size": 0.5, "far_size": 15.0}}, "mode": "grid",
                "vary": {"lining.thickness": [0.2, 0.3], "loads.surface_load": [2.0e4, 1.0e9]}}


def test_the_sweep_page_keeps_warned_rows_one_line_high_and_links_every_case(service, browser, tmp_path):
    url, _ = service
    sweep_id = httpx.post(f"{url}/sweeps", json=WARNED_SWEEP).json()["id"]
    wait_until(lambda: httpx.get(f"{url}/sweeps/{sweep_id}").json()["finished"], timeout=120, what="the sweep")
    table = httpx.get(f"{url}/sweeps/{sweep_id}/table").json()
    warned = {r["case_id"]: r["warnings"] for r in table["rows"] if r["warnings"]}
    assert len(warned) == 2 and all(r["status"] == "done" for r in table["rows"])
    browser.get(f"{url}/ui/sweeps/{sweep_id}")
    headers = [th.get_attribute("data-col") for th in browser.find_elements(By.CSS_SELECTOR, "#comparison-table th")]
    assert headers[:3] == ["lining_thickness", "loads_surface_load", "max_utilization"]
    assert "warnings" not in headers
    rows = browser.find_elements(By.CSS_SELECTOR, "#comparison-table tbody tr")
    assert len(rows) == 4
    heights = {}
    for row in rows:
        case_id = row.get_attribute("data-key")
        heights[case_id] = row.size["height"]
        # every row links to its case
        assert row.find_element(By.CSS_SELECTOR, "a.case-link").get_attribute("href") == f"{url}/ui/cases/{case_id}"
        icons = row.find_elements(By.CSS_SELECTOR, "span.warn-icon")
        if case_id in warned:  # the warnings on hover, not in the row
            assert [i.text for i in icons] == ["⚠"] and icons[0].get_attribute("title") == warned[case_id]
            assert "small-displacement" in warned[case_id] and "small-displacement" not in row.text
        else:
            assert not icons
    plain = [h for c, h in heights.items() if c not in warned]
    assert max(heights[c] for c in warned) <= min(plain) + 0.5, heights  # a warned row is no taller
    assert max(plain) < 60, heights  # one line
    # the workbook beside the CSV, and no reliability figure for a grid
    xlsx = browser.find_element(By.ID, "download-xlsx").get_attribute("href")
    assert xlsx == f"{url}/sweeps/{sweep_id}/summary.xlsx"
    assert httpx.get(xlsx).content[:2] == b"PK"
    assert not browser.find_elements(By.CSS_SELECTOR, "img[data-plot=reliability]")
    wait_until(lambda: (w := images_loaded(browser, "#plots img")) and len(w) == 4 and all(w),
               timeout=60, what="the sweep plots to load")
    screenshot(browser, tmp_path / "sweep-warned.png")


@pytest.mark.parametrize("kind, body, field", [
    ("cases", {"geometry": {"thickness": -0.3}}, "geometry.thickness"),
    ("sweeps", {"name": "bad", "base": SMALL, "vary": {"ground.young": [5e7, -1.0]}}, "ground.young"),
])
def test_a_bad_field_is_shown_beside_the_input_and_nothing_is_stored(service, browser, tmp_path, kind, body, field):
    url, results = service
    before = (httpx.get(f"{url}/cases").json()["total"], httpx.get(f"{url}/sweeps").json()["total"])
    browser.get(url + "/ui/submit")
    browser.find_element(By.CSS_SELECTOR, f"input[name=kind][value={kind}]").click()
    text = browser.find_element(By.ID, "body")
    text.clear()
    text.send_keys(json.dumps(body))
    browser.find_element(By.ID, "submit").click()
    errors = browser.find_element(By.ID, "errors")
    wait_until(errors.is_displayed, timeout=20, what="the error list")
    items = browser.find_elements(By.CSS_SELECTOR, "#error-list li")
    assert any(li.get_attribute("data-field").startswith(field) and li.text.startswith(field) for li in items), \
        [li.text for li in items]
    # beside the textarea: to its right, overlapping it vertically
    box, area = errors.rect, text.rect
    assert box["x"] >= area["x"] + area["width"] and box["y"] < area["y"] + area["height"]
    assert browser.current_url.endswith("/ui/submit")
    screenshot(browser, tmp_path / f"submit-{kind}-error.png")
    after = (httpx.get(f"{url}/cases").json()["total"], httpx.get(f"{url}/sweeps").json()["total"])
    assert after == before


def test_cancel_keeps_queued_cases_from_running_and_they_can_be_submitted_again(service, cluster, browser, tmp_path,
                                                                               request):
    from distributed import Client

    url, results = service
    # keep the only worker busy with a task of our own, so the sweep's cases stay queued (a case
    # chosen to be long ran in 0.45 s on a fast host: done before the service's poll saw it running)
    dask = Client(cluster, timeout=30)
    request.addfinalizer(dask.close)
    hold = dask.submit(time.sleep, 5.0, pure=False)
    wait_until(lambda: any(dask.processing().values()), timeout=30, what="the worker to take the holding task")
    sweep = {"name": "to-cancel", "base": SMALL, "vary": {"ground.young": [3e7, 4e7, 6e7]}}
    accepted = httpx.post(f"{url}/sweeps", json=sweep).json()
    sweep_id, ids = accepted["id"], accepted["case_ids"]
    assert accepted["counts"]["queued"] == 3

    response = httpx.post(f"{url}/sweeps/{sweep_id}/cancel")
    assert response.status_code == 200
    body = response.json()
    assert sorted(body["cancelled_now"]) == sorted(ids)
    assert body["counts"] == {"queued": 0, "running": 0, "done": 0, "failed": 0, "cancelled": 3}
    assert body["finished"]

    # the page says so too
    browser.get(f"{url}/ui/sweeps/{sweep_id}")
    assert "3 cancelled" in browser.find_element(By.ID, "sweep-status").text
    assert state_shown(browser) == ("0,0,0,0,3", "cancelled")
    assert column(browser, "status") == ["cancelled"] * 3
    screenshot(browser, tmp_path / "sweep-cancelled.png")

    # the worker frees up and runs nothing of the cancelled sweep
    hold.result(timeout=60)
    time.sleep(2.0)  # several scheduler polls: a cancelled task that was still queued would have run
    assert httpx.get(f"{url}/sweeps/{sweep_id}").json()["counts"]["cancelled"] == 3
    assert not any(as_store(results).case_path(c).exists() for c in ids)
    assert httpx.get(f"{url}/health").json()["running"] == 0

    # a cancelled case can be submitted again, alone or with its sweep; its page follows
    browser.get(f"{url}/ui/cases/{ids[0]}")
    browser.execute_script("window.__marker = 'same page'")
    assert case_status_shown(browser) == "cancelled"
    again = httpx.post(f"{url}/cases", json=httpx.get(f"{url}/cases/{ids[0]}").json()["spec"])
    assert again.status_code == 202 and again.json()["created"] and again.json()["status"] == "queued"
    wait_until(lambda: case_status_shown(browser) == "done", timeout=60, what="the case page to show done")
    wait_until(lambda: (w := images_loaded(browser, ".plots img")) and len(w) == len(PLOTS) and all(w),
               timeout=60, what="the case plots to load")
    assert browser.execute_script("return window.__marker") == "same page"
    browser.get(url + "/")  # the list follows too
    browser.execute_script("window.__marker = 'same page'")
    assert index_state_shown(browser, sweep_id) == "cancelled"
    resubmitted = httpx.post(f"{url}/sweeps", json=sweep).json()
    assert resubmitted["new_cases"] == 2
    done = wait_until(lambda: (s := httpx.get(f"{url}/sweeps/{sweep_id}").json())["finished"] and s,
                      timeout=60, what="the resubmitted cases")
    assert done["counts"]["done"] == 3 and done["counts"]["cancelled"] == 0
    wait_until(lambda: index_state_shown(browser, sweep_id) == "finished", timeout=20,
               what="the list to show the sweep finished")
    assert browser.execute_script("return window.__marker") == "same page"
    assert all(as_store(results).case_path(c).exists() for c in ids)


def test_the_form_posts_a_case_typed_in_engineering_units(service, browser, tmp_path):
    """MPa, kN/m³, mm, cm²/m typed in the labelled form arrive in the case as SI; a refused
    value is marked on its own input."""
    url, _ = service
    browser.get(url + "/ui/submit")
    assert browser.find_element(By.ID, "case-fields").is_displayed()  # the form is the default
    assert not browser.find_element(By.ID, "body").is_displayed()

    def field(path):
        return browser.find_element(By.CSS_SELECTOR, f"[data-path='{path}']")

    # the defaults shown in the form's units
    assert field("ground.young").get_attribute("value") == "50"  # MPa
    assert field("ground.density").get_attribute("value") == "19.62"  # kN/m³ = 2000 kg/m³ × 9.81
    label = field("ground.young").find_element(By.XPATH, "..").text
    assert "MPa" in label
    for path, value in (("ground.young", "80"), ("ground.density", "20"), ("geometry.gap", "2"),
                        ("design.reinforcement_area", "10"), ("loads.surface_load", "50"),
                        ("mesh.interface_size", "0.25")):
        field(path).clear()
        field(path).send_keys(value)
    browser.find_element(By.ID, "submit").click()
    wait_until(lambda: "/ui/cases/" in browser.current_url, timeout=20, what="the case page")
    case_id = browser.current_url.rsplit("/", 1)[1]
    spec = httpx.get(f"{url}/cases/{case_id}").json()["spec"]
    assert spec["ground"]["young"] == pytest.approx(8.0e7)
    assert spec["ground"]["density"] == pytest.approx(20e3 / 9.81)
    assert spec["geometry"]["gap"] == pytest.approx(0.002)
    assert spec["design"]["reinforcement_area"] == pytest.approx(1.0e-3)
    assert spec["loads"]["surface_load"] == pytest.approx(5.0e4)

    browser.get(url + "/ui/submit")
    field("geometry.thickness").clear()
    field("geometry.thickness").send_keys("-0.3")
    browser.find_element(By.ID, "submit").click()
    wait_until(lambda: "invalid" in field("geometry.thickness").get_attribute("class"), timeout=20,
               what="the refused field marked")
    assert browser.current_url.endswith("/ui/submit")
    screenshot(browser, tmp_path / "submit-form-error.png")


def test_the_json_tab_takes_over_what_the_form_holds(service, browser):
    """Typed in the form (MPa, m), then the "case (JSON)" tab: its text is the form's case in SI, as
    the form would post it (issue 39 item 10)."""
    url, _ = service
    browser.get(url + "/ui/submit")

    def field(path):
        return browser.find_element(By.CSS_SELECTOR, f"[data-path='{path}']")

    for path, value in (("ground.young", "80"), ("geometry.thickness", "0.35"), ("loads.lateral_ratio", "0.7")):
        field(path).clear()
        field(path).send_keys(value)
    browser.find_element(By.CSS_SELECTOR, "input[name=kind][value=cases]").click()
    text = browser.find_element(By.ID, "body")
    assert text.is_displayed()
    case = json.loads(text.get_attribute("value"))
    assert case["ground"]["young"] == pytest.approx(8.0e7)
    assert case["geometry"]["thickness"] == pytest.approx(0.35)
    assert case["loads"]["lateral_ratio"] == pytest.approx(0.7)


def test_the_form_takes_a_horseshoe_section_installed_behind_the_face(service, browser):
    """The form's section and face fields (issue 40): a horseshoe template and a face distance
    typed in (λd emptied: found, not given) arrive as the case's section and excavation."""
    url, _ = service
    browser.get(url + "/ui/submit")

    def field(path):
        return browser.find_element(By.CSS_SELECTOR, f"[data-path='{path}']")

    from selenium.webdriver.support.ui import Select

    Select(field("geometry.section.shape")).select_by_visible_text("horseshoe")
    for path, value in (("geometry.section.crown_radius", "3"), ("geometry.section.crown_angle", "60"),
                        ("geometry.section.side_radius", "4"), ("geometry.section.side_angle", "45"),
                        ("excavation.face_distance", "2"), ("mesh.interface_size", "0.25")):
        field(path).clear()
        field(path).send_keys(value)
    field("excavation.deconfinement").clear()
    Select(field("excavation.ldp")).select_by_visible_text("panet")
    browser.find_element(By.ID, "submit").click()
    wait_until(lambda: "/ui/cases/" in browser.current_url, timeout=20, what="the case page")
    spec = httpx.get(f"{url}/cases/{browser.current_url.rsplit('/', 1)[1]}").json()["spec"]
    assert spec["geometry"]["section"]["shape"] == "polycentric"  # the template as the arcs it expands to
    assert spec["geometry"]["section"]["arcs"][0] == {"radius": 3.0, "angle": 60.0}
    assert spec["excavation"]["face_distance"] == 2.0 and spec["excavation"]["ldp"] == "panet"
    assert spec["excavation"].get("deconfinement") is None


def test_a_token_protected_service_works_from_the_browser(browser, tmp_path):
    """TUNNEL_CONTACT_TOKEN_READS: the browser asks once (HTTP basic authentication, the token
    as the password; given here in the address) and then every page, figure and the
    dashboard's own fetch calls carry it; without it the page is refused."""
    token = "tok-" + "x" * 12
    env = {"TUNNEL_CONTACT_TOKEN": token, "TUNNEL_CONTACT_TOKEN_READS": "1"}
    with running_service(tmp_path / "results", log=tmp_path / "api.log", env=env) as url:
        auth = {"Authorization": f"Bearer {token}"}
        case_id = httpx.post(url + "/cases", json=SMALL, headers=auth, timeout=30).json()["id"]
        wait_until(lambda: httpx.get(f"{url}/cases/{case_id}", headers=auth, timeout=30).json()["status"] == "done",
                   timeout=120, what="the case")
        assert httpx.get(f"{url}/ui/cases/{case_id}", timeout=30).status_code == 401
        with_credentials = url.replace("http://", f"http://engineer:{token}@")
        browser.get(f"{with_credentials}/")  # what the user types at the browser's prompt, once
        browser.get(f"{url}/ui/cases/{case_id}")  # from then on the browser sends it by itself
        assert case_status_shown(browser) == "done"
        wait_until(lambda: images_loaded(browser, "img") and all(images_loaded(browser, "img")),
                   timeout=60, what="the figures")
        fetched = browser.execute_async_script(
            "const done = arguments[arguments.length - 1];"
            "fetch('/cases', {cache: 'no-store'}).then(r => done(r.status), e => done(String(e)));")
        assert fetched == 200
