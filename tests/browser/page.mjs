// The upload page, scenario by scenario, in Debian's chromium. Run from tests/service/browser.rs:
//   node page.mjs BASE SCENARIO DIR [API_KEY]
// DIR holds the test's files (room.xyz, other.xyz, trajectory.json, poses.json, bad.json) and
// receives screenshots. Prints one JSON line with what it saw; exits non-zero on a failed check.
import { chromium } from "playwright-core";
import { readFileSync } from "node:fs";
import { createRequire } from "node:module";

const [base, scenario, dir, apiKey] = process.argv.slice(2);
const require = createRequire(import.meta.url);
const executablePath = process.env.CHROMIUM || "/usr/bin/chromium";
const browser = await chromium.launch({ executablePath, args: ["--no-sandbox", "--disable-gpu"] });
const seen = { scenario };
const fail = async (why) => {
  console.log(JSON.stringify(seen));
  console.error("browser check failed (" + scenario + "): " + why);
  await browser.close();
  process.exit(1);
};
const check = async (ok, why) => { if (!ok) await fail(why); };
const file = (name) => dir + "/" + name;

// A hand-written plan with everything the page can draw: two rooms and a door, wall samples,
// given and estimated scanners, a note, and one side of the outline without a fitted wall.
const samples = [];
for (let i = 0; i <= 80; i++) samples.push([i * 0.05, 0], [i * 0.05, 3]);
for (let i = 0; i <= 60; i++) samples.push([0, i * 0.05], [4, i * 0.05]);
const RICH = {
  type: "FeatureCollection",
  floorplan: {
    version: 1, units: "m", crs: null,
    input: { points: 123456, format: "laz", scans: 2, viewpoints: { source: "mixed", rests_on: 0.75, open_space: [],
      // A walk along y = 2.5 at scanner height, then up the stairs out of the story (not drawn).
      path: { source: "given", samples: 6, windows: 0, located: 0, residual_m: null, length_m: 4.5,
              positions: [[0.5, 2.5, -0.2], [1.5, 2.5, -0.2], [2.5, 2.5, -0.2], [3.5, 2.5, -0.2], [3.5, 2.0, 1.8], [3.5, 1.5, 2.5]] },
      scans: [{ index: 0, source: "given", position: [1, 1.5, 0.2], residual_m: null, support: null, points: 1000 },
              { index: 1, source: "estimated", position: [3, 1.5, 0.2], residual_m: 0.02, support: 0.9, points: 1000 }] } },
    parameters: { samples: { cell_size: 0.05, min_points: null, min_points_derived: [12], point_spacing: 0.012 }, smoothing: { registration_error: null } },
    timings_ms: { read: 1, stories: 1, samples: 1, label: 1, cleanup: 1, fit: 1, total: 6 },
    notes: ["story 0: a hand-written note"],
    // Where the fake pipeline's `underlay.png` (50 × 40 cells of 10 cm from -0.5, -0.5) lies.
    underlay: { file: "underlay.png", size: [50, 40], stories: [{ level: 0, pixels: [0, 0, 50, 40], bbox: [-0.5, -0.5, 4.5, 3.5], cell_m: 0.1, slice_z: [-0.5, 0.0], full_count: 100 }] },
  },
  features: [
    { type: "Feature", geometry: { type: "Polygon", coordinates: [[[0, 0], [4, 0], [4, 3], [0, 3], [0, 0]]] }, properties: { kind: "story", level: 0, floor_z: -1.5, ceiling_z: 1.2, area_m2: 12, samples: samples.length } },
    { type: "Feature", geometry: { type: "LineString", coordinates: [[0, 0], [4, 0]] }, properties: { kind: "wall", level: 0, model: "line", length_m: 4, support: 80 } },
    { type: "Feature", geometry: { type: "LineString", coordinates: [[4, 0], [4, 3]] }, properties: { kind: "wall", level: 0, model: "line", length_m: 3, support: 60 } },
    { type: "Feature", geometry: { type: "LineString", coordinates: [[4, 3], [0, 3]] }, properties: { kind: "wall", level: 0, model: "line", length_m: 4, support: 80 } },
    { type: "Feature", geometry: { type: "MultiPoint", coordinates: samples }, properties: { kind: "wall_samples", level: 0 } },
    { type: "Feature", geometry: { type: "Polygon", coordinates: [[[0, 0], [2, 0], [2, 3], [0, 3], [0, 0]]] }, properties: { kind: "room", level: 0, id: "L0-R1", area_m2: 6, perimeter_m: 10, neighbours: ["L0-R2"] } },
    { type: "Feature", geometry: { type: "Polygon", coordinates: [[[2, 0], [4, 0], [4, 3], [2, 3], [2, 0]]] }, properties: { kind: "room", level: 0, id: "L0-R2", area_m2: 6, perimeter_m: 10, neighbours: ["L0-R1"] } },
    { type: "Feature", geometry: { type: "LineString", coordinates: [[2, 1], [2, 2]] }, properties: { kind: "door", level: 0, id: "L0-D1", width_m: 1, head_z: 0.6, depth_m: 0.1, rooms: ["L0-R1", "L0-R2"] } },
  ],
};
const richPlan = (page) => page.route(/\/v1\/jobs\/[^/]+\/plan\.geojson$/, (r) => r.fulfill({ contentType: "application/geo+json", body: JSON.stringify(RICH) }));

async function open({ path, ...opts } = {}) {
  const ctx = await browser.newContext({ viewport: { width: 1280, height: 900 }, acceptDownloads: true, ...opts });
  const page = await ctx.newPage();
  const external = [], errors = [];
  // The page's own blob URLs (the underlay image, downloads) are local too.
  page.on("request", (r) => { if (!r.url().startsWith(base) && !r.url().startsWith("blob:" + base)) external.push(r.url()); });
  page.on("pageerror", (e) => errors.push(String(e)));
  page.on("dialog", (d) => d.accept());
  page.checkClean = async () => {
    await check(!external.length, "external requests: " + external.join(", "));
    await check(!errors.length, "page errors: " + errors.join("; "));
  };
  if (apiKey) await page.addInitScript((k) => localStorage.setItem("asbuilt.key", k), apiKey);
  await page.goto(base + (path || "/"));
  await page.waitForSelector("#p-samples\\.cell_size", { timeout: 10000 });
  return page;
}
// Waits for `fn(arg)` to be true in the page. (waitForFunction polls with eval, which the page's
// CSP forbids.)
async function until(page, fn, arg, timeout = 20000) {
  const end = Date.now() + timeout;
  while (!(await page.evaluate(fn, arg))) {
    if (Date.now() > end) throw new Error("timed out waiting for " + fn.toString());
    await new Promise((r) => setTimeout(r, 50));
  }
}
// Fetches a job through the page (with its key).
const job = (page, id) => page.evaluate(async (id) => (await api("/v1/jobs/" + id)).json(), id);
const currentId = (page) => page.evaluate(() => current && current.id);
async function uploadAndWait(page, files) {
  if (files) await page.setInputFiles("#file", files);
  await page.click("#start");
  await page.waitForSelector("#plan[data-drawn=true]", { timeout: 60000 });
  await page.locator("#viewer").scrollIntoViewIfNeeded();
  return currentId(page);
}
// The screen position of a plan point (world metres) in the drawn view.
const screenOf = (page, x, y) => page.evaluate(([x, y]) => {
  const r = $("plan").getBoundingClientRect();
  const s = Math.max(view.w / r.width, view.h / r.height);
  const ox = view.x + view.w / 2 - (r.width / 2) * s, oy = view.y + view.h / 2 - (r.height / 2) * s;
  const q = tx([x, y]);
  return [r.left + (q[0] - ox) / s, r.top + (q[1] - oy) / s];
}, [x, y]);
async function axe(page) {
  await page.addScriptTag({ content: readFileSync(require.resolve("axe-core/axe.min.js"), "utf8") });
  const res = await page.evaluate(async () => (await axe.run(document, { resultTypes: ["violations"] })).violations
    .map((v) => v.id + ": " + v.nodes.map((n) => n.target.join(" ")).slice(0, 4).join(", ")));
  return res;
}

try {
  if (scenario === "mobile") {
    // A trajectory goes as `trajectory`, found from the file's content; a bad sidecar never leaves.
    const page = await open();
    await page.setInputFiles("#file", [file("room.xyz"), file("bad.json")]);
    await until(page, () => !$("sidecarinfo").textContent.startsWith("reading"));
    seen.badInfo = await page.textContent("#sidecarinfo");
    seen.badStart = await page.isDisabled("#start");
    await check(seen.badInfo.includes("neither poses") && seen.badStart, "a bad sidecar was not refused in the page");
    await page.setInputFiles("#poses", file("trajectory.json"));
    await until(page, () => $("sidecarinfo").textContent.includes("trajectory"));
    seen.kind = await page.inputValue("#sidecarkind");
    await check(seen.kind === "trajectory", "trajectory not recognised: " + seen.kind);
    let sent = null;
    page.on("request", (r) => { if (r.method() === "POST" && r.url().includes("/v1/jobs")) sent = r.postDataBuffer(); });
    await page.click("#start");
    await page.waitForSelector("#plan[data-drawn=true]", { timeout: 60000 });
    const j = await job(page, await currentId(page));
    seen.sidecar = j.upload.sidecar;
    await check(seen.sidecar === "trajectory", "the job's sidecar is " + seen.sidecar);
    // Chromium shows a body with files only sometimes; when it does, the sidecar comes first.
    if (sent) {
      const body = sent.toString("latin1");
      seen.partOrder = [body.indexOf('name="trajectory"'), body.indexOf('name="cloud"')];
      await check(seen.partOrder[0] >= 0 && seen.partOrder[0] < seen.partOrder[1], "the sidecar part must go before the cloud: " + seen.partOrder);
    }
    seen.upload = await page.textContent("#uptext");
    await check(seen.upload.includes("with its trajectory"), "upload summary: " + seen.upload);
    await check((await page.textContent("#q-poses")).includes("trajectory"), "quality does not say the trajectory was used");
    await page.checkClean();
  } else if (scenario === "stale") {
    // Poses belong to one upload: cleared after it, dropped with a new cloud, removable by hand.
    const page = await open();
    await page.setInputFiles("#file", [file("room.xyz"), file("poses.json")]);
    await until(page, () => $("sidecarinfo").textContent.includes("poses of 1 scan"));
    const first = await uploadAndWait(page, null);
    seen.first = (await job(page, first)).upload.sidecar;
    await check(seen.first === "poses", "the first job's sidecar: " + seen.first);
    seen.afterUpload = { ctl: await page.isHidden("#sidecarctl"), chosen: await page.textContent("#chosen"), start: await page.isDisabled("#start") };
    await check(seen.afterUpload.ctl && seen.afterUpload.start && seen.afterUpload.chosen.includes("No scan"), "state kept after an upload: " + JSON.stringify(seen.afterUpload));
    // A cloud and its poses chosen, then a different cloud chosen on its own: the poses go.
    await page.setInputFiles("#file", file("room.xyz"));
    await page.setInputFiles("#poses", file("poses.json"));
    await until(page, () => !$("sidecarctl").hidden);
    await page.setInputFiles("#file", file("other.xyz"));
    seen.dropped = await page.textContent("#sidecarinfo");
    await check(seen.dropped.includes("previous scan") && (await page.isHidden("#sidecarctl")), "poses kept with a new cloud: " + seen.dropped);
    // The remove control.
    await page.setInputFiles("#poses", file("poses.json"));
    await until(page, () => !$("sidecarctl").hidden);
    await page.click("#sidecarremove");
    seen.removed = await page.evaluate(() => !posesFile() && $("sidecarctl").hidden);
    await check(seen.removed, "remove did not remove the poses");
    await page.click("#start");
    await until(page, (f) => current && current.id !== f, first);
    await page.waitForSelector("#plan[data-drawn=true]", { timeout: 60000 });
    seen.second = (await job(page, await currentId(page))).upload.sidecar;
    await check(seen.second === null, "the second job got a sidecar: " + seen.second);
    // A refused file leaves no stale bar.
    await page.setInputFiles("#file", file("refused.txt"));
    await page.click("#start");
    await until(page, () => $("uperr").textContent.length > 0);
    seen.refused = { err: await page.textContent("#uperr"), bar: await page.isHidden("#upload"), start: await page.isEnabled("#start") };
    await check(seen.refused.err.startsWith("Refused") && seen.refused.bar && seen.refused.start, "refusal state: " + JSON.stringify(seen.refused));
    // An upload can be aborted: slow the network, start, abort.
    const cdp = await page.context().newCDPSession(page);
    await cdp.send("Network.enable");
    await cdp.send("Network.emulateNetworkConditions", { offline: false, latency: 0, downloadThroughput: -1, uploadThroughput: 200 * 1024 });
    await page.setInputFiles("#file", file("big.xyz"));
    await page.click("#start");
    await until(page, () => !$("abort").hidden);
    seen.busyStart = await page.isDisabled("#start");
    await page.click("#abort");
    await until(page, () => $("uperr").textContent.includes("aborted"));
    seen.aborted = { bar: await page.isHidden("#upload"), abort: await page.isHidden("#abort"), start: await page.isEnabled("#start") };
    await check(seen.busyStart && seen.aborted.bar && seen.aborted.abort && seen.aborted.start, "abort: " + JSON.stringify(seen.aborted));
    await cdp.send("Network.emulateNetworkConditions", { offline: false, latency: 0, downloadThroughput: -1, uploadThroughput: -1 });
    // A cancelled job leaves no stage running.
    await page.setInputFiles("#file", file("hang.xyz"));
    await page.click("#start");
    await until(page, () => !$("cancel").hidden && document.querySelector("#stages li.now"));
    await page.click("#cancel");
    await until(page, () => $("status").textContent.startsWith("cancelled"));
    seen.cancelled = await page.evaluate(() => ({ now: document.querySelectorAll("#stages li.now").length, stopped: [...document.querySelectorAll("#stages li.stopped")].map((l) => l.textContent), cancel: $("cancel").hidden }));
    await check(seen.cancelled.now === 0 && seen.cancelled.stopped.length === 1 && seen.cancelled.cancel, "after cancel: " + JSON.stringify(seen.cancelled));
    await page.checkClean();
  } else if (scenario === "warnings") {
    // Parameters checked in the page, in words; warnings and notes in yellow; skipped stages.
    const page = await open();
    seen.angle = await page.inputValue("#p-smoothing\\.max_angle");
    await check(seen.angle === "22.5", "the radian default is not shown in degrees: " + seen.angle);
    seen.label = await page.textContent("label[for='p-samples.cell_size']");
    await check(seen.label.includes(", m"), "no unit on the cell size: " + seen.label);
    const width = await page.evaluate(() => [...document.querySelectorAll(".params input")].every((i) => { const r = i.getBoundingClientRect(), s = i.closest("section").getBoundingClientRect(); return r.width === 0 || r.right <= s.right; }));
    await check(width, "an input wider than its card");
    await page.fill("#p-samples\\.cell_size", "5cm");
    seen.cmNote = await page.textContent("#p-samples\\.cell_size-err");
    await check(seen.cmNote.includes("0.05 m"), "5cm not read as 0.05 m: " + seen.cmNote);
    await page.fill("#p-samples\\.cell_size", "five");
    await page.setInputFiles("#file", file("room.xyz"));
    let posted = 0;
    page.on("request", (r) => { if (r.method() === "POST") posted++; });
    await page.click("#start");
    seen.paramErr = await page.textContent("#uperr");
    seen.focused = await page.evaluate(() => document.activeElement.id);
    await check(posted === 0 && seen.paramErr.includes("Grid cell size") && seen.paramErr.includes("not a number") && seen.focused === "p-samples.cell_size", "bad parameter: " + JSON.stringify(seen));
    await page.fill("#p-samples\\.cell_size", "0.9");
    await page.click("#start");
    seen.rangeErr = await page.textContent("#uperr");
    await check(seen.rangeErr.includes("0.01 to 0.5 m"), "range not given: " + seen.rangeErr);
    await page.fill("#p-samples\\.cell_size", "5 cm");
    await page.click("#start");
    await page.waitForSelector("#plan[data-drawn=true]", { timeout: 60000 });
    const j = await job(page, await currentId(page));
    seen.sentCell = j.parameters && j.parameters.samples ? j.parameters.samples.cell_size : JSON.stringify(j.parameters);
    await check(Math.abs(seen.sentCell - 0.05) < 1e-9, "5 cm not sent as 0.05: " + seen.sentCell);
    seen.status = await page.textContent("#status");
    seen.statusColor = await page.evaluate(() => getComputedStyle($("status")).color);
    seen.viewWarning = await page.textContent("#viewwarn");
    seen.skipped = await page.evaluate(() => [...document.querySelectorAll("#stages li.skipped")].map((l) => l.textContent));
    seen.done = await page.evaluate(() => [...document.querySelectorAll("#stages li.done")].map((l) => l.textContent));
    await check(seen.status === "succeeded" && seen.statusColor === "rgb(107, 78, 0)", "status not yellow: " + seen.statusColor);
    await check(seen.skipped.join() === "smoothing" && !seen.done.includes("smoothing"), "smoothing not shown as skipped: " + seen.skipped);
    // A plan with notes: listed in the yellow box.
    await richPlan(page);
    await page.evaluate(async (id) => show(await (await api("/v1/jobs/" + id)).json()), j.id);
    await until(page, () => !$("notes").hidden);
    seen.notes = await page.textContent("#notes");
    seen.viewWarnRich = await page.textContent("#viewwarn");
    await check(seen.notes.includes("a hand-written note") && seen.notes.includes("79 %"), "notes: " + seen.notes);
    await check(seen.viewWarnRich.includes("1 of 2 scans") && seen.viewWarnRich.includes("75 %"), "viewpoint warning: " + seen.viewWarnRich);
    seen.coverage = await page.textContent("#storytable td.coverage");
    await check(seen.coverage === "79 %", "outline share: " + seen.coverage);
    seen.minpoints = await page.textContent("#q-minpoints");
    await check(seen.minpoints.includes("12"), "derived min. points not shown: " + seen.minpoints);
    // Progress of a three-story run, replayed: the story count, a skipped stage, a failure.
    const ev = (o) => "event: job\ndata: " + JSON.stringify({ ...j, status: "running", error: null, timings_ms: null, ...o }) + "\n\n";
    const runs = [["read", 0], ["stories", 0], ["samples", 0], ["label", 0.5 / 3], ["cleanup", 0.8 / 3], ["fit", 0.9 / 3], ["samples", 1 / 3], ["label", 1.5 / 3]];
    await page.route(/\/events$/, (r) => r.fulfill({ contentType: "text/event-stream", body: runs.map(([stage, progress]) => ev({ stage, progress })).join("") }));
    await page.evaluate((j) => show({ ...j, status: "running", stage: "read", progress: 0 }), j);
    await until(page, () => $("storyinfo").textContent.length > 0);
    seen.story = await page.textContent("#storyinfo");
    seen.runSkipped = await page.evaluate(() => [...document.querySelectorAll("#stages li.skipped")].map((l) => l.textContent));
    await check(seen.story === "story 2 of 3", "story: " + seen.story);
    await check(seen.runSkipped.join() === "smoothing", "skipped while running: " + seen.runSkipped);
    await page.unroute(/\/events$/);
    // Reading: the bar follows the bytes read; then the server's story count wins over the guess.
    const mib = 1048576;
    await page.route(/\/events$/, (r) => r.fulfill({ contentType: "text/event-stream", body: [ev({ stage: "read", progress: 0, read: { bytes: 5 * mib, total: 20 * mib } })].join("") }));
    await page.evaluate((j) => show({ ...j, status: "running", stage: "read", progress: 0 }), j);
    await until(page, () => $("jobtext").textContent.includes("of 20.0 MB"));
    seen.reading = { text: await page.textContent("#jobtext"), width: await page.evaluate(() => $("jobbar").style.width), busy: await page.evaluate(() => $("jobbarwrap").classList.contains("busy")) };
    await check(seen.reading.text.includes("5.0 MB of 20.0 MB") && seen.reading.width === "25%" && !seen.reading.busy, "reading: " + JSON.stringify(seen.reading));
    await page.unroute(/\/events$/);
    await page.route(/\/events$/, (r) => r.fulfill({ contentType: "text/event-stream", body: [ev({ stage: "samples", progress: 0.5, story: { number: 3, count: 4 } })].join("") }));
    await page.evaluate((j) => show({ ...j, status: "running", stage: "read", progress: 0 }), j);
    await until(page, () => $("storyinfo").textContent.length > 0);
    seen.serverStory = await page.textContent("#storyinfo");
    await check(seen.serverStory === "story 3 of 4", "the server's story: " + seen.serverStory);
    await page.unroute(/\/events$/);
    await page.route(/\/events$/, (r) => r.fulfill({ contentType: "text/event-stream", body: ev({ stage: "label", progress: 0.2, status: "failed", error: { code: "labeling_failed", message: "no room" } }) }));
    await page.evaluate((j) => show({ ...j, status: "running", stage: "read", progress: 0 }), j);
    await until(page, () => $("status").textContent === "failed");
    seen.failedChip = await page.evaluate(() => [...document.querySelectorAll("#stages li.failed")].map((l) => l.textContent));
    seen.downloadsOff = await page.evaluate(() => [...document.querySelectorAll("#downloads button")].every((b) => b.disabled));
    await check(seen.failedChip.join() === "label" && seen.downloadsOff, "failed stage: " + seen.failedChip);
    // With a parameter error shown, the open parameter list and a failed job: still no violations.
    await page.fill("#p-samples\\.cell_size", "five");
    await page.click("summary");
    seen.axe = await axe(page);
    await check(seen.axe.length === 0, "axe violations: " + seen.axe.join("; "));
    await page.checkClean();
  } else if (scenario === "underlay") {
    // Wall samples under the plan, scanners, rooms and a door; toggles; downloads named by scan.
    const page = await open();
    await richPlan(page);
    await uploadAndWait(page, file("room.xyz"));
    seen.samples = await page.locator("#g-samples path.samples").count();
    seen.image = await page.locator("#g-underlay svg.underlay image").count();
    seen.path = await page.evaluate(() => [...document.querySelectorAll("#plan polyline.scanpath")].map((p) => [p.getAttribute("class"), p.getAttribute("points").split(" ").length, p.getAttribute("stroke-dasharray")]));
    await check(seen.image === 1, "no image of the points: " + seen.image);
    // The path within the story (four positions; those up the stairs are left out), solid: given.
    await check(JSON.stringify(seen.path) === JSON.stringify([["scanpath given", 4, null]]), "scanner path: " + JSON.stringify(seen.path));
    seen.given = await page.locator("#plan circle.viewpoint.given").count();
    seen.estimated = await page.locator("#plan circle.viewpoint.estimated").count();
    seen.rooms = await page.locator("#plan path.room").count();
    seen.labels = await page.evaluate(() => [...document.querySelectorAll("#plan text.roomlabel")].map((t) => t.textContent));
    seen.doors = await page.locator("#plan polyline.door").count();
    await check(seen.samples === 1 && seen.given === 1 && seen.estimated === 1 && seen.rooms === 2 && seen.doors === 1, "layers: " + JSON.stringify(seen));
    await check(seen.labels.includes("L0-R1 · 6.0 m²"), "room labels: " + seen.labels);
    seen.legend = await page.evaluate(() => [...document.querySelectorAll("#legend span")].filter((s) => !s.hidden).map((s) => s.id).filter(Boolean));
    await check(["samplelegend", "givenlegend", "estlegend", "roomlegend", "doorlegend", "pointslegend", "pathlegend"].every((id) => seen.legend.includes(id)) && !seen.legend.includes("arclegend"), "legend: " + seen.legend);
    seen.pathLegend = await page.textContent("#pathlegend");
    seen.slice = await page.textContent("#pointslegend");
    await check(seen.pathLegend.includes("given") && seen.slice.includes("1.00–1.50 m above the floor"), "legend text: " + seen.pathLegend + " / " + seen.slice);
    // An estimated path is dashed, and says so.
    const estimated = JSON.parse(JSON.stringify(RICH));
    estimated.floorplan.input.viewpoints.path.source = "estimated";
    await page.unroute(/\/v1\/jobs\/[^/]+\/plan\.geojson$/);
    await page.route(/\/v1\/jobs\/[^/]+\/plan\.geojson$/, (r) => r.fulfill({ contentType: "application/geo+json", body: JSON.stringify(estimated) }));
    await page.evaluate(async () => show(await (await api("/v1/jobs/" + current.id)).json()));
    // Attached, not visible: a straight horizontal line has no height.
    await page.waitForSelector("#plan[data-drawn=true] polyline.scanpath.estimated", { state: "attached" });
    seen.dashed = await page.getAttribute("#plan polyline.scanpath.estimated", "stroke-dasharray");
    seen.pathLegendEst = await page.textContent("#pathlegend");
    await check(seen.dashed === "6 4" && seen.pathLegendEst.includes("estimated"), "estimated path: " + seen.dashed + " / " + seen.pathLegendEst);
    await page.fill("#opacity", "30");
    seen.opacity = await page.getAttribute("#g-underlay", "opacity");
    await page.uncheck("#underlay");
    seen.hidden = await page.evaluate(() => getComputedStyle(document.querySelector("#g-underlay")).display);
    await check(seen.opacity === "0.3" && seen.hidden === "none", "underlay toggle: " + seen.opacity + " " + seen.hidden);
    await page.check("#underlay");
    await page.uncheck("#showsamples");
    seen.samplesHidden = await page.evaluate(() => getComputedStyle(document.querySelector("#g-samples")).display);
    await check(seen.samplesHidden === "none", "samples toggle");
    await page.check("#showsamples");
    await page.uncheck("#showrooms");
    seen.roomsHidden = await page.evaluate(() => getComputedStyle(document.querySelector("#g-rooms")).display);
    await check(seen.roomsHidden === "none", "rooms toggle");
    await page.check("#showrooms");
    const [dl] = await Promise.all([page.waitForEvent("download"), page.click("#downloads button[data-ext=svg]")]);
    seen.download = dl.suggestedFilename();
    await check(/^room-\d{8}-\d{6}\.svg$/.test(seen.download), "download name: " + seen.download);
    await page.screenshot({ path: file("underlay.png") });
    await page.checkClean();
  } else if (scenario === "points") {
    // The server's own plan and image: the points under the plan, decoded by the browser.
    const page = await open();
    const id = await uploadAndWait(page, file("room.xyz"));
    const j = await job(page, id);
    await check(typeof j.links.underlay === "string" && j.links.underlay.endsWith("/underlay.png"), "no underlay link: " + JSON.stringify(j.links));
    // The fake image spans -0.5..4.5 × -0.5..3.5 m: its north-west corner where the plan draws that point.
    seen.box = await page.evaluate(() => { const s = document.querySelector("#g-underlay svg.underlay"); return s && { at: ["x", "y", "width", "height"].map((k) => Number(s.getAttribute(k))), want: tx([-0.5, 3.5]), viewBox: s.getAttribute("viewBox") }; });
    await check(seen.box && Math.abs(seen.box.at[0] - seen.box.want[0]) < 1e-9 && Math.abs(seen.box.at[1] - seen.box.want[1]) < 1e-9 && seen.box.at[2] === 5 && seen.box.at[3] === 4 && seen.box.viewBox === "0 0 50 40", "image placed at " + JSON.stringify(seen.box));
    // Pixels as the browser decodes them: a wall dark and opaque, the floor pale, outside clear.
    seen.pixels = await page.evaluate(async () => {
      const img = document.querySelector("#g-underlay image");
      // The CSP lets images, not fetch, read blob URLs.
      const bitmap = new Image();
      bitmap.src = img.getAttribute("href");
      await bitmap.decode();
      const c = document.createElement("canvas"); c.width = bitmap.width; c.height = bitmap.height;
      const g = c.getContext("2d"); g.drawImage(bitmap, 0, 0);
      const at = (i, j) => [...g.getImageData(i, bitmap.height - 1 - j, 1, 1).data];
      return { size: [bitmap.width, bitmap.height], wall: at(5, 20), floor: at(20, 20), outside: at(1, 1) };
    });
    await check(seen.pixels.size.join() === "50,40" && seen.pixels.wall[3] === 255 && seen.pixels.wall[0] < 40 && seen.pixels.floor[3] > 0 && seen.pixels.floor[3] < 100 && seen.pixels.outside[3] === 0, "pixels: " + JSON.stringify(seen.pixels));
    // Under the walls, over the floor: the group order says so.
    seen.order = await page.evaluate(() => [...$("plan").children].map((g) => g.id));
    await check(seen.order.indexOf("g-area") < seen.order.indexOf("g-underlay") && seen.order.indexOf("g-underlay") < seen.order.indexOf("g-walls"), "layer order: " + seen.order);
    await page.fill("#opacity", "25");
    seen.opacity = await page.getAttribute("#g-underlay", "opacity");
    await page.uncheck("#underlay");
    seen.hidden = await page.evaluate(() => getComputedStyle(document.querySelector("#g-underlay")).display);
    seen.opacityOff = await page.isDisabled("#opacity");
    await check(seen.opacity === "0.25" && seen.hidden === "none" && seen.opacityOff, "toggle and opacity: " + JSON.stringify([seen.opacity, seen.hidden, seen.opacityOff]));
    await page.check("#underlay");
    // The page plans with the points in the SVG: its download carries them as a layer.
    await check(j.parameters.svg_underlay === true, "svg_underlay not sent: " + JSON.stringify(j.parameters));
    const [dl] = await Promise.all([page.waitForEvent("download"), page.click("#downloads button[data-name=svg]")]);
    const svg = readFileSync(await dl.path(), "utf8");
    seen.svgLayer = /<g class="underlay" id="underlay-0"[^>]*><title>[^<]*<\/title><image [^>]*href="data:image\/png;base64,[A-Za-z0-9+/=]+"/.test(svg);
    await check(seen.svgLayer, "no underlay layer in the SVG");
    seen.axe = await axe(page);
    await check(seen.axe.length === 0, "axe violations: " + seen.axe.join("; "));
    await page.screenshot({ path: file("points.png") });
    await page.checkClean();
  } else if (scenario === "measure") {
    // Cursor coordinates, a measured distance, a wall's length on hover.
    const page = await open();
    await richPlan(page);
    await uploadAndWait(page, file("room.xyz"));
    const [ax, ay] = await screenOf(page, 0.5, 0.5);
    const [bx, by] = await screenOf(page, 3.5, 2.5);
    await page.mouse.move(ax, ay);
    seen.cursor = await page.textContent("#cursor");
    await check(seen.cursor === "x 0.50 m, y 0.50 m", "cursor: " + seen.cursor);
    await page.click("#measure");
    await page.mouse.click(ax, ay);
    await page.mouse.click(bx, by);
    seen.measured = Number(await page.getAttribute("#measureout", "data-metres"));
    await check(Math.abs(seen.measured - Math.hypot(3, 2)) < 0.02, "measured " + seen.measured);
    await check((await page.locator("#g-measure line.measureline").count()) === 1, "no measure line");
    await page.click("#measure");
    const [wx, wy] = await screenOf(page, 4, 1.5);
    await page.mouse.move(wx + 3, wy);
    seen.wall = await page.textContent("#wallinfo");
    await check(seen.wall.includes("3.00 m long"), "wall on hover: " + seen.wall);
    await page.checkClean();
  } else if (scenario === "reload") {
    // The job's address survives a reload; the list pages; finished jobs can be deleted.
    const page = await open();
    const id = await uploadAndWait(page, file("room.xyz"));
    seen.hash = new URL(page.url()).hash;
    await check(seen.hash === "#job=" + id, "no job in the address: " + seen.hash);
    await page.reload();
    await page.waitForSelector("#plan[data-drawn=true]", { timeout: 20000 });
    seen.afterReload = await currentId(page);
    await check(seen.afterReload === id, "reload lost the job");
    const p2 = await open({ path: "/?job=" + id });
    await p2.waitForSelector("#plan[data-drawn=true]", { timeout: 20000 });
    await check((await currentId(p2)) === id, "?job= not opened");
    const missing = await open({ path: "/#job=00000000-0000-7000-8000-000000000000" });
    await until(missing, () => $("joberr").textContent.length > 0);
    seen.missing = await missing.textContent("#joberr");
    await check(seen.missing.includes("not found"), "missing job: " + seen.missing);
    // The server already holds 12 jobs (the test made 11 more): 10 on a page, then the rest.
    await page.waitForSelector("#jobs li[data-id]");
    seen.firstPage = await page.locator("#jobs li[data-id]").count();
    await check(seen.firstPage === 10 && (await page.isVisible("#more")), "first page: " + seen.firstPage);
    await page.click("#more");
    await until(page, () => document.querySelectorAll("#jobs li[data-id]").length > 10);
    seen.allPages = await page.locator("#jobs li[data-id]").count();
    await check(seen.allPages === 12 && (await page.isHidden("#more")), "after more: " + seen.allPages);
    seen.sameNames = await page.evaluate(() => new Set([...document.querySelectorAll("#jobs li[data-id] .when")].map((w) => w.textContent)).size);
    await check(seen.sameNames === 12, "same-named jobs look alike");
    const victim = await page.getAttribute("#jobs li[data-id]:not(.current) >> nth=0", "data-id");
    await page.click(`#jobs li[data-id="${victim}"] button.del`);
    await until(page, (v) => !document.querySelector(`#jobs li[data-id="${v}"]`), victim);
    seen.deleted = await page.evaluate(async (v) => (await fetch("/v1/jobs/" + v, { headers: auth() })).status, victim);
    await check(seen.deleted === 404, "deleted job still there: " + seen.deleted);
    await page.checkClean();
  } else if (scenario === "keyboard") {
    // Everything from the keyboard, then axe-core.
    const page = await open();
    await richPlan(page);
    const id = await uploadAndWait(page, file("room.xyz"));
    const other = await page.evaluate(async () => (await (await api("/v1/jobs?limit=10")).json()).jobs.map((j) => j.id));
    const target = other.find((j) => j !== id);
    await page.evaluate(() => { document.activeElement.blur(); window.scrollTo(0, 0); });
    // Tab to the other job's open button and press Enter.
    let reached = false;
    for (let i = 0; i < 200 && !reached; i++) {
      await page.keyboard.press("Tab");
      reached = await page.evaluate((t) => { const a = document.activeElement; return a && a.classList.contains("open") && a.closest("li").dataset.id === t; }, target);
    }
    await check(reached, "the job list cannot be reached with Tab");
    await page.keyboard.press("Enter");
    await until(page, (t) => current && current.id === t && $("plan").dataset.drawn === "true", target);
    // Focus the plan with Tab; zoom, pan and measure from the keyboard.
    reached = false;
    for (let i = 0; i < 200 && !reached; i++) { await page.keyboard.press("Tab"); reached = await page.evaluate(() => document.activeElement.id === "plan"); }
    await check(reached, "the plan cannot be focused with Tab");
    const vb0 = await page.getAttribute("#plan", "viewBox");
    await page.keyboard.press("+");
    const vb1 = await page.getAttribute("#plan", "viewBox");
    await page.keyboard.press("ArrowRight");
    const vb2 = await page.getAttribute("#plan", "viewBox");
    const n = (vb, k) => Number(vb.split(" ")[k]);
    await check(n(vb1, 2) < n(vb0, 2) && n(vb2, 0) > n(vb1, 0), "keys did not zoom and pan: " + [vb0, vb1, vb2].join(" | "));
    await page.keyboard.press("0");
    await check((await page.getAttribute("#plan", "viewBox")) === vb0, "0 did not fit");
    for (let i = 0; i < 30 && !(await page.evaluate(() => document.activeElement.id === "measure")); i++) await page.keyboard.press("Shift+Tab");
    await page.keyboard.press("Enter");
    for (let i = 0; i < 30 && !(await page.evaluate(() => document.activeElement.id === "plan")); i++) await page.keyboard.press("Tab");
    await check(await page.evaluate(() => document.activeElement.id === "plan" && measure.on), "measure mode not reached from the keyboard");
    await page.keyboard.press("Enter");
    await page.keyboard.press("ArrowRight");
    await page.keyboard.press("Enter");
    seen.kbMeasure = Number(await page.getAttribute("#measureout", "data-metres"));
    await check(seen.kbMeasure > 0, "no measurement from the keyboard");
    seen.focusRing = await page.evaluate(() => getComputedStyle(document.activeElement).outlineStyle);
    await check(seen.focusRing !== "none", "no visible focus");
    await page.keyboard.press("Escape");
    seen.axe = await axe(page);
    await check(seen.axe.length === 0, "axe violations: " + seen.axe.join("; "));
    await page.checkClean();
  } else if (scenario === "phone") {
    // A phone: tap a job and see it, pinch to zoom, tap a wall for its length.
    const page = await open({ viewport: { width: 390, height: 844 }, hasTouch: true, isMobile: true, deviceScaleFactor: 2 });
    await richPlan(page);
    await uploadAndWait(page, file("room.xyz"));
    await page.evaluate(() => window.scrollTo(0, document.body.scrollHeight));
    await page.locator("#jobs li[data-id] button.open").first().tap();
    await until(page, () => $("plan").dataset.drawn === "true");
    // The tapped job's plan is fetched, drawn, then scrolled to: on a loaded machine that can
    // take longer than any fixed pause, so wait for it (the check below still fails if never).
    const shown = () => Math.abs($("plansec").getBoundingClientRect().top) < 50;
    await until(page, shown, undefined, 10000).catch(() => {});
    seen.planTop = await page.evaluate(() => $("plansec").getBoundingClientRect().top);
    await check(Math.abs(seen.planTop) < 50, "tapping a job did not bring its plan into view: " + seen.planTop);
    await page.locator("#plan").scrollIntoViewIfNeeded();
    const box = await page.locator("#plan").boundingBox();
    const cdp = await page.context().newCDPSession(page);
    const cx = box.x + box.width / 2, cy = box.y + box.height / 2;
    const touch = (type, d) => cdp.send("Input.dispatchTouchEvent", { type, touchPoints: type === "touchEnd" ? [] : [{ x: cx - d, y: cy, id: 1 }, { x: cx + d, y: cy, id: 2 }] });
    const vb0 = (await page.getAttribute("#plan", "viewBox")).split(" ").map(Number);
    await touch("touchStart", 30);
    for (let d = 40; d <= 120; d += 20) await touch("touchMove", d);
    await touch("touchEnd", 0);
    const vb1 = (await page.getAttribute("#plan", "viewBox")).split(" ").map(Number);
    seen.pinch = vb0[2] / vb1[2];
    await check(seen.pinch > 2.5 && seen.pinch < 5, "pinch did not zoom about 4×: " + seen.pinch);
    await page.click("#fit");
    const [wx, wy] = await screenOf(page, 2, 0);
    await page.touchscreen.tap(wx, wy + 6);
    seen.tapWall = await page.textContent("#wallinfo");
    await check(seen.tapWall.includes("4.00 m long"), "tap on a wall: " + seen.tapWall);
    // Measuring by touch: two taps.
    await page.locator("#measure").tap();
    const [ax, ay] = await screenOf(page, 0.5, 0.5), [bx, by] = await screenOf(page, 3.5, 0.5);
    await page.touchscreen.tap(ax, ay);
    await page.touchscreen.tap(bx, by);
    seen.tapMeasure = Number(await page.getAttribute("#measureout", "data-metres"));
    await check(Math.abs(seen.tapMeasure - 3) < 0.05, "measured by touch: " + seen.tapMeasure);
    const overflow = await page.evaluate(() => document.documentElement.scrollWidth - window.innerWidth);
    await check(overflow <= 0, "the page is wider than the phone by " + overflow + " px");
    seen.axe = await axe(page);
    await check(seen.axe.length === 0, "axe violations on a phone: " + seen.axe.join("; "));
    await page.screenshot({ path: file("phone.png"), fullPage: true });
    await page.checkClean();
  } else if (scenario === "outputs") {
    // Downloads follow the job's `links`; a running job is cancelled, kept, and shows its expiry.
    const page = await open();
    const requests = [];
    page.on("request", (r) => { if (r.method() !== "GET") requests.push(r.method() + " " + new URL(r.url()).pathname); });
    const id = await uploadAndWait(page, file("room.xyz"));
    const j = await job(page, id);
    const offered = Object.keys(j.links).filter((k) => k !== "self" && k !== "events");
    seen.offered = offered;
    seen.buttons = await page.evaluate(() => [...document.querySelectorAll("#downloads button")].map((b) => b.dataset.name));
    await check(offered.includes("ifc") && offered.includes("rooms") && JSON.stringify([...seen.buttons].sort()) === JSON.stringify([...offered].sort()), "buttons " + seen.buttons + " for links " + offered);
    await check(seen.buttons[0] === "geojson", "GeoJSON (the contract) is not first: " + seen.buttons);
    seen.labels = await page.evaluate(() => [...document.querySelectorAll("#downloads button")].map((b) => b.textContent));
    // Each download from the keyboard: its name, and the bytes the server serves under the link.
    seen.names = {};
    for (const name of offered) {
      await page.focus(`#downloads button[data-name="${name}"]`);
      const [dl] = await Promise.all([page.waitForEvent("download"), page.keyboard.press("Enter")]);
      const got = readFileSync(await dl.path());
      const served = await page.evaluate(async (href) => (await (await api(href)).arrayBuffer()).byteLength, j.links[name]);
      seen.names[name] = dl.suggestedFilename();
      const ext = j.links[name].split(".").pop();
      const own = j.links[name].split("/").pop().replace(/\.[^.]*$/, "");
      const want = new RegExp("^room-\\d{8}-\\d{6}" + (own === "plan" ? "" : "-" + own) + "\\." + ext + "$");
      await check(want.test(seen.names[name]), name + " saved as " + seen.names[name]);
      await check(got.length > 0 && got.length === served, name + ": " + got.length + " bytes saved, " + served + " served");
      if (name === "ifc") await check(got.toString("latin1").startsWith("ISO-10303-21"), "the IFC download is not STEP");
      if (name === "rooms") await check(got.toString("utf8").split("\n")[0].includes(","), "the rooms download is not CSV");
    }
    await check(seen.labels.includes("IFC") && seen.labels.includes("Rooms CSV") && seen.labels.includes("GeoJSON"), "labels: " + seen.labels);
    // A format the server adds later: one more link, one more button, no page change.
    await page.route(new RegExp("/v1/jobs/" + id + "$"), async (r) => {
      const res = await r.fetch();
      const body = await res.json();
      body.links.pdf = "/v1/jobs/" + id + "/plan.pdf";
      await r.fulfill({ response: res, json: body });
    });
    await page.route(new RegExp("/v1/jobs/" + id + "/plan\\.pdf$"), (r) => r.fulfill({ contentType: "application/pdf", body: "%PDF-1.7 test" }));
    await page.evaluate(async (id) => show(await (await api("/v1/jobs/" + id)).json()), id);
    await page.waitForSelector("#downloads button[data-name=pdf]");
    const [pdf] = await Promise.all([page.waitForEvent("download"), page.click("#downloads button[data-name=pdf]")]);
    seen.pdf = [await page.textContent("#downloads button[data-name=pdf]"), pdf.suggestedFilename()];
    await check(seen.pdf[0] === "PDF" && /^room-\d{8}-\d{6}\.pdf$/.test(seen.pdf[1]), "a new link: " + seen.pdf);
    await page.unroute(new RegExp("/v1/jobs/" + id + "$"));
    // A finished job says how long it is kept.
    seen.expires = await page.textContent("#expires");
    seen.expiresAt = await page.getAttribute("#expires time", "datetime");
    await check(j.expires_at && seen.expires.startsWith("kept until ") && seen.expiresAt === j.expires_at, "expiry: " + seen.expires + " / " + seen.expiresAt + " / " + j.expires_at);
    // Cancel a running job from the keyboard: kept as cancelled, with its stage stopped.
    await page.setInputFiles("#file", file("hang.xyz"));
    await page.click("#start");
    await until(page, () => !$("cancel").hidden && document.querySelector("#stages li.now"));
    const running = await currentId(page);
    seen.runningExpires = await page.textContent("#expires");
    seen.runningDownloads = await page.locator("#downloads button").count();
    await check(seen.runningExpires === "" && seen.runningDownloads === 0, "a running job shows expiry or downloads");
    await page.focus("#cancel");
    await page.keyboard.press("Enter");
    await until(page, () => $("status").textContent.startsWith("cancelled"));
    // The cancel button goes away: focus moves to the status, not to the page's start.
    await until(page, () => document.activeElement.id === "status", null, 5000).catch(() => {});
    seen.focusAfterCancel = await page.evaluate(() => document.activeElement.id);
    await check(seen.focusAfterCancel === "status", "focus after cancel: " + seen.focusAfterCancel);
    const c = await job(page, running);
    seen.cancelled = { status: c.status, stopped: await page.locator("#stages li.stopped").count(), expires: await page.getAttribute("#expires time", "datetime") };
    await check(c.status === "cancelled" && seen.cancelled.stopped === 1 && c.expires_at && seen.cancelled.expires === c.expires_at, "after cancel: " + JSON.stringify(seen.cancelled));
    seen.requests = requests.filter((r) => r.includes(running));
    await check(seen.requests.join() === "POST /v1/jobs/" + running + "/cancel", "cancel sent: " + seen.requests);
    await until(page, (r) => { const li = document.querySelector(`#jobs li[data-id="${r}"]`); return li && li.querySelector(".st").textContent === "cancelled" && li.querySelector("button.del"); }, running);
    await check(await page.isHidden("#cancel"), "cancel still offered for a cancelled job");
    seen.axe = await axe(page);
    await check(seen.axe.length === 0, "axe violations: " + seen.axe.join("; "));
    await page.checkClean();
  } else if (scenario === "replan") {
    // Plan again from the stored upload, with the form's parameters and optionally new poses.
    const page = await open();
    const posts = [];
    page.on("request", (r) => { if (r.method() === "POST") posts.push(new URL(r.url()).pathname); });
    await page.fill("#p-samples\\.cell_size", "4 cm");
    await page.setInputFiles("#file", [file("room.xyz"), file("poses.json")]);
    await until(page, () => $("sidecarinfo").textContent.includes("poses of 1 scan"));
    const first = await uploadAndWait(page, null);
    await check(await page.isVisible("#replanbox"), "no plan-again control on a finished job");
    seen.replanName = await page.textContent("#replanname");
    await check(seen.replanName === "room.xyz", "plan again names " + seen.replanName);
    // Other parameters, then Tab to the button and Enter.
    await page.fill("#p-samples\\.cell_size", "0.1");
    await page.focus("#p-samples\\.cell_size");
    let reached = false;
    for (let i = 0; i < 200 && !reached; i++) { await page.keyboard.press("Tab"); reached = await page.evaluate(() => document.activeElement.id === "replan"); }
    await check(reached, "plan again cannot be reached with Tab");
    await page.keyboard.press("Enter");
    await until(page, (f) => current && current.id !== f, first);
    const second = await currentId(page);
    seen.followed = await page.evaluate(() => $("status").textContent);
    await page.waitForSelector("#plan[data-drawn=true]", { timeout: 60000 });
    const j2 = await job(page, second);
    seen.second = { source: j2.source_job, cell: j2.parameters.samples.cell_size, sidecar: j2.upload.sidecar, hash: new URL(page.url()).hash };
    await check(seen.second.source === first && seen.second.cell === 0.1 && seen.second.sidecar === "poses" && seen.second.hash === "#job=" + second, "first re-plan: " + JSON.stringify(seen.second));
    await check(seen.followed !== "succeeded" || (await page.locator("#stages li.done").count()) > 0, "the new job was not followed");
    seen.posts = posts.slice();
    await check(posts.join() === "/v1/jobs,/v1/jobs/" + first + "/replan", "requests: " + posts);
    await until(page, (id) => document.querySelector(`#jobs li[data-id="${id}"]`), second);
    seen.listed = await page.textContent(`#jobs li[data-id="${second}"] .when`);
    await check(seen.listed.includes("planned again"), "the list does not tell the re-plan: " + seen.listed);
    await check(await page.isHidden("#upload"), "the first upload's bar is left after the re-plan");
    // The form's values are what is sent: back to defaults, and a trajectory in place of the poses.
    const dflt = await page.evaluate(() => defaults.samples.cell_size);
    await page.click("#resetparams");
    await page.setInputFiles("#replanposes", file("trajectory.json"));
    await until(page, () => $("replansidecar").textContent.includes("trajectory"));
    await page.click("#replan");
    await until(page, (s) => current && current.id !== s, second);
    await page.waitForSelector("#plan[data-drawn=true]", { timeout: 60000 });
    const j3 = await job(page, await currentId(page));
    seen.third = { source: j3.source_job, cell: j3.parameters.samples.cell_size, sidecar: j3.upload.sidecar, dflt };
    // A re-plan of a re-plan still names the job whose upload it reads.
    await check(seen.third.source === first && seen.third.cell === dflt && dflt !== 0.1 && seen.third.sidecar === "trajectory", "second re-plan: " + JSON.stringify(seen.third));
    await check((await page.textContent("#q-poses")).includes("trajectory"), "quality does not say the trajectory was used");
    await check((await page.inputValue("#replanposes")) === "" && (await page.textContent("#replansidecar")) === "", "the new poses stay chosen after the re-plan");
    // Nothing leaves with a bad parameter or a bad sidecar.
    const before = posts.length;
    await page.fill("#p-samples\\.cell_size", "five");
    await page.click("#replan");
    seen.paramErr = await page.textContent("#replanerr");
    seen.focused = await page.evaluate(() => document.activeElement.id);
    await check(seen.paramErr.includes("Grid cell size") && seen.focused === "p-samples.cell_size", "bad parameter: " + seen.paramErr);
    await page.click("#resetparams");
    await page.setInputFiles("#replanposes", file("bad.json"));
    await until(page, () => $("replansidecar").textContent.includes("neither"));
    await page.click("#replan");
    seen.sideErr = await page.textContent("#replanerr");
    await page.screenshot({ path: file("replan.png"), fullPage: true });
    await check(seen.sideErr.includes("neither poses") && posts.length === before, "bad sidecar: " + seen.sideErr + ", posts " + posts.slice(before));
    seen.axe = await axe(page);
    await check(seen.axe.length === 0, "axe violations: " + seen.axe.join("; "));
    await page.checkClean();
  } else {
    await fail("unknown scenario " + scenario);
  }
} catch (e) {
  await fail(e.stack || String(e));
}
console.log(JSON.stringify(seen));
await browser.close();
