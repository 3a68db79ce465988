// Uploads a cloud through the page at BASE, waits for the plan to be drawn, checks it, and
// saves a screenshot. Usage: node upload.mjs BASE CLOUD SCREENSHOT [API_KEY]
// POSES=FILE adds a pose sidecar. Prints one JSON line with what it saw; exits non-zero on any failed check.
import { chromium } from "playwright-core";

const [base, cloud, shot, apiKey] = process.argv.slice(2);
const executablePath = process.env.CHROMIUM || "/usr/bin/chromium";
const browser = await chromium.launch({ executablePath, args: ["--no-sandbox", "--disable-gpu"] });
const fail = async (why) => {
  console.error("browser check failed: " + why);
  await browser.close();
  process.exit(1);
};
try {
  const page = await browser.newPage({ viewport: { width: 1280, height: 860 } });
  const external = [];
  // The page's own blob URLs (the underlay image, downloads) are local too.
  page.on("request", (r) => { if (!r.url().startsWith(base) && !r.url().startsWith("blob:" + base)) external.push(r.url()); });
  const errors = [];
  page.on("pageerror", (e) => errors.push(String(e)));
  await page.goto(base + "/");
  if (apiKey) {
    await page.fill("#apikey", apiKey);
    await page.dispatchEvent("#apikey", "change");
  }
  // Defaults are shown before anything is uploaded.
  await page.waitForSelector("#p-samples\\.cell_size", { timeout: 10000 });
  if (process.env.POSES) await page.setInputFiles("#poses", process.env.POSES);
  await page.setInputFiles("#file", cloud);
  // Choosing a file only selects it; nothing is sent until the button is pressed.
  const chosen = await page.textContent("#chosen");
  if (!chosen.includes(cloud.split("/").pop())) await fail("chosen file not shown: " + chosen);
  if ((await page.locator("#jobs li[data-id]").count()) !== 0) await fail("a job started before Upload");
  await page.click("#start");
  await page.waitForSelector("#plan[data-drawn=true]", { timeout: 90000 });
  await page.waitForSelector("#jobs li.current", { timeout: 10000 });
  const seen = await page.evaluate(() => ({
    status: document.getElementById("status").textContent,
    walls: document.querySelectorAll("#plan polyline.wall").length,
    arcs: document.querySelectorAll("#plan polyline.arc").length,
    areas: document.querySelectorAll("#plan path.area").length,
    scale: document.getElementById("scaletext").textContent,
    downloads: [...document.querySelectorAll("#downloads button")].filter((b) => !b.disabled).length,
    // One download per result the job's links name.
    offered: Object.keys((current && current.links) || {}).filter((k) => k !== "self" && k !== "events").length,
    stages: [...document.querySelectorAll("#stages li.done")].length,
    upload: document.getElementById("uptext").textContent,
    jobs: document.querySelectorAll("#jobs li").length,
    current: document.querySelectorAll("#jobs li.current").length,
    legend: document.querySelectorAll(".legend span").length,
    arcLegend: !document.getElementById("arclegend").hidden,
    cancelHidden: document.getElementById("cancel").hidden,
    viewWarning: document.getElementById("viewwarn").hidden ? "" : document.getElementById("viewwarn").textContent,
    statusWarn: document.getElementById("status").classList.contains("warn"),
    notes: document.getElementById("notes").hidden ? "" : document.getElementById("notes").textContent,
    statusColor: getComputedStyle(document.getElementById("status")).color,
  }));
  await page.screenshot({ path: shot, fullPage: true });
  // Zoom in: the scale bar must follow.
  const before = seen.scale + " " + (await page.getAttribute("#plan", "viewBox"));
  const box = await page.locator("#plan").boundingBox();
  await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  await page.mouse.wheel(0, -400);
  await page.waitForTimeout(200);
  seen.zoomedScale = (await page.textContent("#scaletext")) + " " + (await page.getAttribute("#plan", "viewBox"));
  console.log(JSON.stringify({ ...seen, external, errors }));
  if (seen.status !== "succeeded") await fail("status is " + seen.status);
  if (seen.walls < 1 || seen.areas < 1) await fail("no plan drawn");
  if (seen.arcLegend !== seen.arcs > 0) await fail("arc legend shown: " + seen.arcLegend + ", arcs: " + seen.arcs);
  if (seen.downloads < 5 || seen.downloads !== seen.offered) await fail("downloads: " + seen.downloads + " for " + seen.offered + " results");
  if (seen.current !== 1) await fail("the shown job is not marked in the list");
  if (!seen.cancelHidden) await fail("cancel still offered for a finished job");
  if (!seen.upload.includes("SHA-256")) await fail("no upload summary");
  if (seen.zoomedScale === before) await fail("zoom changed nothing: " + before);
  if (seen.zoomedScale.split(" ")[0] === before.split(" ")[0] && seen.zoomedScale.split(" ")[1] === before.split(" ")[1])
    await fail("scale bar did not follow the zoom: " + before + " → " + seen.zoomedScale);
  if (external.length) await fail("external requests: " + external.join(", "));
  if (errors.length) await fail("page errors: " + errors.join("; "));
} catch (e) {
  await fail(e.stack || String(e));
}
await browser.close();
