// Screenshots of the page with a real scan planned, at desktop and phone sizes (for docs/).
//   [API_KEY=KEY] node screenshots.mjs BASE CLOUD OUTDIR [SIDECAR]
// Uploads CLOUD (and SIDECAR) through the page, waits for the plan (up to 15 minutes), and
// writes page-desktop.png, page-desktop-plan.png (the plan over its points), page-desktop-quality.png,
// page-phone-plan.png and page-phone-progress.png.
import { chromium } from "playwright-core";

const [base, cloud, out, sidecar] = process.argv.slice(2);
const browser = await chromium.launch({ executablePath: process.env.CHROMIUM || "/usr/bin/chromium", args: ["--no-sandbox", "--disable-gpu"] });
try {
  const key = process.env.API_KEY;
  const context = async (opts) => {
    const ctx = await browser.newContext(opts);
    if (key) await ctx.addInitScript((k) => localStorage.setItem("asbuilt.key", k), key);
    return ctx.newPage();
  };
  const desk = await context({ viewport: { width: 1366, height: 900 } });
  await desk.goto(base + "/");
  await desk.waitForSelector("#p-samples\\.cell_size");
  await desk.setInputFiles("#file", sidecar ? [cloud, sidecar] : [cloud]);
  await desk.waitForTimeout(500);
  await desk.click("#start");
  await desk.waitForSelector("#plan[data-drawn=true]", { timeout: 15 * 60 * 1000 });
  const id = await desk.evaluate(() => current.id);
  await desk.evaluate(() => $("progresssec").scrollIntoView());
  await desk.screenshot({ path: out + "/page-desktop.png" });
  await desk.evaluate(() => $("plansec").scrollIntoView());
  await desk.screenshot({ path: out + "/page-desktop-plan.png" });
  await desk.evaluate(() => $("quality").scrollIntoView());
  await desk.screenshot({ path: out + "/page-desktop-quality.png" });
  const phone = await context({ viewport: { width: 390, height: 844 }, hasTouch: true, isMobile: true });
  await phone.goto(base + "/#job=" + id);
  await phone.waitForSelector("#plan[data-drawn=true]", { timeout: 60000 });
  await phone.evaluate(() => $("plansec").scrollIntoView());
  await phone.screenshot({ path: out + "/page-phone-plan.png" });
  await phone.evaluate(() => $("progresssec").scrollIntoView());
  await phone.screenshot({ path: out + "/page-phone-progress.png" });
  const underlay = await desk.evaluate(() => !!document.querySelector("#g-underlay svg.underlay image"));
  console.log(JSON.stringify({ id, underlay, status: await desk.textContent("#status"), notes: await desk.textContent("#notes"), quality: await desk.textContent("#quality") }));
} finally {
  await browser.close();
}
