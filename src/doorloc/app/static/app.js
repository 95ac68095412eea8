// doorloc operator page: post an image to /v1/locate?overlay=true and show what comes back.
// Errors are shown as the API's own sentence (problem+json "detail", or the result's "error").
"use strict";

const $ = (id) => document.getElementById(id);
const fmt = (v, digits) => (v === null || v === undefined ? "—" : Number(v).toFixed(digits));

// The key lives for this tab only (sessionStorage): closing the tab forgets it, and no other tab or later
// visit can read it.
function apiHeaders() {
  localStorage.removeItem("doorloc.api_key"); // where earlier versions kept it
  const key = $("api_key").value || sessionStorage.getItem("doorloc.api_key") || "";
  if ($("api_key").value) sessionStorage.setItem("doorloc.api_key", $("api_key").value);
  return key ? { "X-API-Key": key } : {};
}

function showError(sentence) {
  const el = $("error");
  el.textContent = sentence;
  el.hidden = !sentence;
}

async function checkReady() {
  const badge = $("ready");
  try {
    const r = await fetch("/readyz");
    const body = await r.json();
    badge.textContent = r.ok ? "ready" : "not ready";
    badge.className = "badge " + (r.ok ? "ok" : "bad");
    badge.title = r.ok ? body.cell_id : body.detail;
  } catch (e) {
    badge.textContent = "unreachable";
    badge.className = "badge bad";
  }
}

function fillRows(tbody, rows) {
  tbody.replaceChildren(...rows.map((cells) => {
    const tr = document.createElement("tr");
    for (const c of cells) {
      const td = document.createElement("td");
      td.textContent = c;
      tr.appendChild(td);
    }
    return tr;
  }));
}

function showAnswer(a) {
  $("answer").hidden = false;
  $("image-name").textContent = a.image;
  $("status").textContent = a.ok ? "located" : "refused";
  $("status").className = "badge " + (a.ok ? "ok" : "bad");
  $("pose-x").textContent = fmt(a.x_mm, 3);
  $("pose-z").textContent = fmt(a.z_mm, 3);
  $("pose-yaw").textContent = fmt(a.yaw_deg, 4);
  // a cell with locate.thickness_check: report answers a door whose thickness the image could not verify;
  // the operator must see that, and why, next to the value
  $("pose-thickness").textContent = fmt(a.thickness_mm, 2) + (a.thickness_verified === false ? " (not verified)" : "");
  $("pose-thickness").title = a.thickness_unverified_reason || "";
  $("pose-scale").textContent = fmt(a.scale_mm_per_px, 5);
  $("pose-corner").textContent = a.corner_px ? a.corner_px.map((v) => fmt(v, 2)).join(", ") : "—";
  $("pose-elapsed").textContent = fmt(a.elapsed_ms, 0);
  showUncertainty(a);
  if (a.overlay_png) {
    $("overlay").src = "data:image/png;base64," + a.overlay_png;
  } else {
    $("overlay").removeAttribute("src");
  }
  fillRows($("quality").tBodies[0], (a.lines || []).map((l) => [
    l.name, `${l.n_inliers}/${l.n_points}`, fmt(l.rms_residual_px, 3), fmt(l.rms_residual_mm, 4), fmt(l.contrast, 1),
  ]));
  $("targets-note").textContent = a.targets_note || "";
  fillRows($("targets").tBodies[0], (a.targets || []).map((t) => [
    t.name, t.hinge ?? "", fmt(t.x_mm, 3), fmt(t.y_mm, 3), fmt(t.z_mm, 3), (t.quat || []).map((q) => fmt(q, 5)).join(" "),
  ]));
  showReach(a.reach);
  showError(a.ok ? "" : a.error);
}

// Each pose value's 1-sigma, and the uncertainty term that contributes most to it: by its name in
// diagnostics.uncertainty_budget ([{source, x_mm, z_mm, yaw_deg, thickness_mm}]) where the answer has one,
// else in diagnostics.uncertainty_terms ({name: [x_mm, z_mm, yaw_deg]}, no thickness part).
function dominantTerm(d, key, index) {
  const parts = Array.isArray(d.uncertainty_budget)
    ? d.uncertainty_budget.map((t) => [t.source, t[key]])
    : Object.entries(d.uncertainty_terms || {}).map(([name, t]) => [name, index === null ? null : t[index]]);
  const best = parts.filter(([, v]) => typeof v === "number" && v > 0).sort((p, q) => q[1] - p[1])[0];
  return best ? String(best[0]).replaceAll("_", " ") : "";
}

function showUncertainty(a) {
  const u = a.uncertainty || {};
  const d = a.diagnostics || {};
  const thickness = a.ok && d.thickness_check ? d.thickness_check.sigma_mm : null;
  for (const [row, key, index, sigma] of [
    ["x", "x_mm", 0, u.x_mm], ["z", "z_mm", 1, u.z_mm], ["yaw", "yaw_deg", 2, u.yaw_deg],
    ["thickness", "thickness_mm", null, thickness],
  ]) {
    const known = sigma !== null && sigma !== undefined;
    $("sigma-" + row).textContent = known ? "± " + Number(sigma).toPrecision(2) : "—";
    $("dominant-" + row).textContent = known ? dominantTerm(d, key, index) : "";
  }
}

// The reach block (SPEC section 9): present when the cell names a robot and there were targets.
function showReach(r) {
  $("reach").hidden = !r;
  if (!r) return;
  $("reach-status").textContent = r.feasible ? "feasible" : "not feasible";
  $("reach-status").className = "badge " + (r.feasible ? "ok" : "bad");
  $("reach-note").textContent = `${r.robot}, tool ${r.tool.pos_mm.map((v) => fmt(v, 1)).join(", ")} mm` +
    (r.feasible ? "" : ` — ${r.reason}`);
  fillRows($("reach-targets").tBodies[0], (r.targets || []).map((t) => [
    t.name, t.feasible ? "yes" : "no", (t.joints_deg || []).map((v) => fmt(v, 2)).join(" "),
    (t.confdata || []).join(","), fmt(t.inv_condition, 3), (t.deflection_mm || []).map((v) => fmt(v, 3)).join(" "),
    t.reason || "",
  ]));
}

async function locate(file) {
  if (!file) {
    showError("Choose an image first.");
    return;
  }
  const form = new FormData();
  form.append("image", file, file.name);
  for (const name of ["door_id", "width_mm", "thickness_mm", "height_mm"]) {
    const v = $(name).value.trim();
    if (v) form.append(name, v);
  }
  $("busy").hidden = false;
  $("submit").disabled = true;
  showError("");
  try {
    const r = await fetch("/v1/locate?overlay=true", { method: "POST", body: form, headers: apiHeaders() });
    const body = await r.json().catch(() => null);
    if (!r.ok) {
      $("answer").hidden = true;
      showError((body && body.detail) || `The service answered ${r.status} ${r.statusText}.`);
      return;
    }
    showAnswer(body);
  } catch (e) {
    showError("The service cannot be reached: " + e.message);
  } finally {
    $("busy").hidden = true;
    $("submit").disabled = false;
  }
}

$("locate-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  locate($("image").files[0]);
});
$("image").addEventListener("change", () => locate($("image").files[0]));

const drop = $("drop");
drop.addEventListener("dragover", (ev) => { ev.preventDefault(); drop.classList.add("over"); });
drop.addEventListener("dragleave", () => drop.classList.remove("over"));
drop.addEventListener("drop", (ev) => {
  ev.preventDefault();
  drop.classList.remove("over");
  const file = ev.dataTransfer.files[0];
  if (file) {
    $("image").files = ev.dataTransfer.files;
    locate(file);
  }
});

checkReady();
