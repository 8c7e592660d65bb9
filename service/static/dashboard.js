// tunnel-contact dashboard: keeps the server-rendered pages live without reloading them.
// Each page polls a JSON route; when what it returns changed, the parts of the page
// that show it are rendered again by the server (the same URL) and swapped in.
// No framework, no build step, nothing fetched from outside.
"use strict";
(function () {
  const TC = {};
  window.TC = TC;
  TC.loadedAt = Date.now();  // stays the same for as long as this page object lives

  TC.token = () => localStorage.getItem("tunnel-contact-token") || "";

  TC.post = (url, body) => {
    const headers = {"content-type": "application/json"};
    if (TC.token()) headers["Authorization"] = "Bearer " + TC.token();
    return fetch(url, {method: "POST", headers: headers, body: body});
  };

  TC.getJSON = async (url) => {
    const response = await fetch(url, {cache: "no-store"});
    if (!response.ok) throw new Error(url + ": HTTP " + response.status);
    return response.json();
  };

  // Call fn now and again after the delay (ms) it returns; stop when it returns false.
  TC.poll = (fn, delay) => {
    const tick = async () => {
      let next = delay;
      try { next = await fn(); } catch (err) { console.warn(err); }
      if (next !== false) setTimeout(tick, typeof next === "number" ? next : delay);
    };
    setTimeout(tick, delay);
  };

  // Replace the content of each selector with the same element of this page rendered anew.
  TC.swap = async (selectors) => {
    const response = await fetch(location.href, {cache: "no-store"});
    if (!response.ok) return;
    const fresh = new DOMParser().parseFromString(await response.text(), "text/html");
    for (const selector of selectors) {
      const from = fresh.querySelector(selector), to = document.querySelector(selector);
      if (from && to) {
        to.innerHTML = from.innerHTML;
        for (const {name, value} of from.attributes) to.setAttribute(name, value);
      }
    }
  };

  // -- sorting: click a column header; values from data-value, numbers compared as numbers
  const number = (text) => text === "inf" ? Infinity : text === "-inf" ? -Infinity
    : /^[-+]?[0-9]*\.?[0-9]+([eE][-+]?[0-9]+)?$/.test(text) ? parseFloat(text) : NaN;
  const compare = (a, b) => {
    const x = number(a), y = number(b);
    if (isNaN(x) || isNaN(y)) return String(a).localeCompare(String(b));
    return x === y ? 0 : x < y ? -1 : 1;
  };

  TC.sortTable = (table, sort) => {
    if (!table || !sort.col) return;
    const headers = [...table.tHead.rows[0].cells];
    const index = headers.findIndex((th) => th.dataset.col === sort.col);
    if (index < 0) return;
    headers.forEach((th) => th.removeAttribute("aria-sort"));
    headers[index].setAttribute("aria-sort", sort.dir === "asc" ? "ascending" : "descending");
    const body = table.tBodies[0];
    const value = (row) => {
      const cell = row.cells[index];
      return cell.dataset.value !== undefined ? cell.dataset.value : cell.textContent.trim();
    };
    const rows = [...body.rows];
    rows.sort((r1, r2) => {
      const a = value(r1), b = value(r2);
      if (a === "" || b === "") return (a === "") - (b === "");  // empty cells last, either way
      return sort.dir === "asc" ? compare(a, b) : compare(b, a);
    });
    rows.forEach((row) => body.appendChild(row));
  };

  TC.sortable = (container) => {
    const sort = {col: null, dir: "asc"};
    container.addEventListener("click", (event) => {
      const th = event.target.closest("th[data-col]");
      if (!th) return;
      sort.dir = sort.col === th.dataset.col && sort.dir === "asc" ? "desc" : "asc";
      sort.col = th.dataset.col;
      TC.sortTable(container.querySelector("table"), sort);
    });
    return sort;
  };

  const STATUSES = ["queued", "running", "done", "failed", "cancelled"];
  const signature = (counts) => STATUSES.map((s) => counts[s]).join(",");

  // -- pages ------------------------------------------------------------------------------
  TC.indexPage = () => {
    let last = null;
    TC.poll(async () => {
      const [sweeps, cases] = await Promise.all([
        TC.getJSON("/sweeps?limit=20"), TC.getJSON("/cases?limit=20&newest_first=true")]);
      const now = sweeps.items.map((s) => s.id + ":" + signature(s.counts)).join(";") + "|" +
                  cases.items.map((c) => c.id + ":" + c.status).join(";");
      // the first poll swaps too: what changed between the page's render and this poll
      // (a short sweep may have finished by then) would otherwise never be shown
      if (now !== last) await TC.swap([".strip", "#sweeps", "#cases"]);
      last = now;
      return 2000;
    }, 1000);
  };

  TC.searchPage = (searchId) => {
    // redraw the status and trials when a trial is recorded or the search ends
    const status = () => document.getElementById("search-status");
    TC.poll(async () => {
      const search = await TC.getJSON("/searches/" + searchId);
      if (String(search.trials.length) !== status().dataset.trials || search.status !== status().dataset.status) {
        await TC.swap(["#search-status", "#search-trials"]);
      }
      return search.status === "running" ? 1000 : false;
    }, 1000);
  };

  TC.sweepPage = (sweepId) => {
    const sort = TC.sortable(document.getElementById("comparison"));
    const status = document.getElementById("sweep-status");
    status.addEventListener("click", async (event) => {
      if (event.target.id !== "cancel") return;
      event.target.disabled = true;
      const response = await TC.post("/sweeps/" + sweepId + "/cancel", "");
      const body = await response.json();
      const message = response.ok ? body.cancelled_now.length + " cases cancelled (running ones stop within a second)"
                                  : "not cancelled: " + body.detail;
      await TC.swap(["#sweep-status", "#comparison", "#plots", "#downloads"]);
      TC.sortTable(document.getElementById("comparison-table"), sort);
      document.getElementById("cancel-message").textContent = message;
    });
    // plots are drawn anew for every set of finished cases: at most every 15 s while the
    // sweep runs, and once when it has finished
    let plotsAt = 0;
    TC.poll(async () => {
      const sweep = await TC.getJSON("/sweeps/" + sweepId);
      if (signature(sweep.counts) !== status.dataset.signature) {
        const parts = ["#sweep-status", "#comparison", "#downloads"];
        if (sweep.finished || Date.now() - plotsAt > 15000) {
          parts.push("#plots");
          plotsAt = Date.now();
        }
        await TC.swap(parts);
        TC.sortTable(document.getElementById("comparison-table"), sort);
      }
      return sweep.finished ? 5000 : 1000;
    }, 1000);
  };

  TC.casePage = (caseId) => {
    const main = document.getElementById("case-main");
    TC.poll(async () => {
      const record = await TC.getJSON("/cases/" + caseId);
      if (record.status !== main.dataset.signature) await TC.swap(["#case-main"]);
      return ["queued", "running"].includes(record.status) ? 1000 : 3000;
    }, 1000);
  };

  TC.submitPage = () => {
    const form = document.getElementById("submit-form");
    const text = document.getElementById("body");
    const token = document.getElementById("token");
    const errors = document.getElementById("errors");
    const list = document.getElementById("error-list");
    const message = document.getElementById("submit-message");
    const examples = JSON.parse(document.getElementById("examples").textContent);
    token.value = TC.token();
    token.addEventListener("change", () => localStorage.setItem("tunnel-contact-token", token.value));
    const fields = document.getElementById("case-fields");
    const jsonField = document.getElementById("json-field");
    const showKind = () => {
      const byForm = form.elements.kind.value === "form";
      fields.hidden = !byForm;
      jsonField.hidden = byForm;
    };
    // the JSON tab takes over what the form holds (the form's case in SI, as it would be posted)
    let lastKind = form.elements.kind.value;
    form.addEventListener("change", (event) => {
      if (event.target.name !== "kind") return;
      if (lastKind === "form" && form.elements.kind.value === "cases") {
        text.value = JSON.stringify(JSON.parse(formCase()), null, 1);
      }
      lastKind = form.elements.kind.value;
      showKind();
    });
    form.addEventListener("click", (event) => {
      const which = event.target.dataset.example;
      if (!which) return;
      text.value = examples[which];
      form.elements.kind.value = which === "case" ? "cases" : "sweeps";
      lastKind = form.elements.kind.value;
      showKind();
    });
    showKind();
    // the form's case as JSON in SI: typed value x factor; a unit weight (factor 0) -> density
    const formCase = () => {
      const inputs = [...fields.querySelectorAll("[data-path]")];
      const gravityInput = inputs.find((i) => i.dataset.path === "loads.gravity");
      const gravity = gravityInput ? Number(gravityInput.value) : 9.81;
      const body = {};
      for (const input of inputs) {
        const raw = input.value.trim();
        if (raw === "") continue;
        const factor = Number(input.dataset.factor);
        let value = raw;
        if (input.tagName !== "SELECT") {
          const number = Number(raw.replace(",", "."));
          // not a number: sent as typed, so the service names the field and the reason
          value = Number.isFinite(number) ? (factor === 0 ? number * 1000 / gravity : number * factor) : raw;
        }
        const parts = input.dataset.path.split(".");
        let node = body;
        for (const part of parts.slice(0, -1)) node = node[part] = node[part] || {};
        node[parts[parts.length - 1]] = value;
      }
      return JSON.stringify(body);
    };
    form.addEventListener("submit", async (event) => {
      event.preventDefault();
      const byForm = form.elements.kind.value === "form";
      const kind = byForm ? "cases" : form.elements.kind.value;
      for (const marked of fields.querySelectorAll(".invalid")) marked.classList.remove("invalid");
      list.replaceChildren();
      errors.hidden = true;
      message.textContent = "submitting…";
      let response;
      try {
        response = await TC.post("/" + kind, byForm ? formCase() : text.value);
      } catch (err) {
        message.textContent = "the service did not answer: " + err;
        return;
      }
      const body = await response.json().catch(() => ({detail: "HTTP " + response.status}));
      if (response.ok) {
        message.textContent = "accepted";
        location.href = "/ui/" + kind + "/" + body.id;
        return;
      }
      message.textContent = "";
      const items = body.errors && body.errors.length ? body.errors : [{field: "body", reason: body.detail}];
      for (const e of items) {
        const li = document.createElement("li");
        const field = document.createElement("code");
        field.className = "field";
        field.textContent = e.field;
        li.dataset.field = e.field;
        li.append(field, ": " + e.reason);
        list.append(li);
        const input = fields.querySelector(`[data-path="${e.field}"]`);
        if (byForm && input) input.classList.add("invalid");
      }
      errors.hidden = false;
    });
  };
})();
