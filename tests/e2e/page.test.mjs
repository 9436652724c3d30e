// End-to-end test of the explorer, as a person uses it: the page is served on 127.0.0.1 and
// driven in Debian's headless Chromium through playwright-core (no browser download).
// Needs the wasm package built into www/pkg (scripts/wasm.sh build). Writes screenshots and
// the measured interaction cost to test-output/e2e/.
import { test, before, after } from "node:test";
import assert from "node:assert/strict";
import { createServer } from "node:http";
import { readFile, mkdir, writeFile, mkdtemp, rm } from "node:fs/promises";
import { existsSync } from "node:fs";
import { join, extname, resolve, dirname } from "node:path";
import { tmpdir } from "node:os";
import { fileURLToPath } from "node:url";
import { chromium } from "playwright-core";

const root = resolve(dirname(fileURLToPath(import.meta.url)), "../..");
const www = join(root, "www");
const out = join(root, "test-output", "e2e");
const TYPES = { ".html": "text/html", ".js": "text/javascript", ".mjs": "text/javascript", ".css": "text/css", ".wasm": "application/wasm", ".json": "application/json", ".svg": "image/svg+xml" };

let server, base, browser, profile, page;
const problems = [];

before(async () => {
  assert.ok(existsSync(join(www, "pkg", "nmci.js")), "www/pkg is missing: run scripts/wasm.sh build first");
  await mkdir(out, { recursive: true });
  server = createServer(async (req, res) => {
    const path = decodeURIComponent(new URL(req.url, "http://x").pathname);
    const file = join(www, path.endsWith("/") ? path + "index.html" : path);
    if (!file.startsWith(www)) return res.writeHead(403).end();
    try {
      const body = await readFile(file);
      res.writeHead(200, { "content-type": TYPES[extname(file)] ?? "application/octet-stream" }).end(body);
    } catch {
      res.writeHead(404).end("not found");
    }
  });
  await new Promise((ok) => server.listen(0, "127.0.0.1", ok));
  base = `http://127.0.0.1:${server.address().port}/`;
  profile = await mkdtemp(join(tmpdir(), "nmci-chromium-"));
  browser = await chromium.launchPersistentContext(profile, {
    executablePath: process.env.CHROMIUM ?? "/usr/bin/chromium",
    headless: true,
    viewport: { width: 1400, height: 900 },
    args: ["--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-background-networking", "--disable-component-update", "--disable-sync", "--disable-quic"],
  });
  page = browser.pages()[0] ?? (await browser.newPage());
  page.on("pageerror", (e) => problems.push(`page error: ${e.message}`));
  page.on("console", (m) => m.type() === "error" && problems.push(`console error: ${m.text()}`));
  await page.goto(base);
  await settle();
});

after(async () => {
  await browser?.close();
  server?.close();
  if (profile) await rm(profile, { recursive: true, force: true });
});

async function settle() {
  await page.waitForFunction(() => document.body.dataset.ready === "true", null, { timeout: 60_000 });
}
const text = (sel) => page.locator(sel).innerText();
const num = async (sel) => Number((await text(sel)).trim());
const cell = (key, i, j) => page.locator(`#grid-${key} input[aria-label="${key === "pa" ? "P_a" : "P_b"}[${i},${j}]"]`);

test("opens on the paper's example: nmCI trace 2.000, ω = [0, 1], CI looser", async () => {
  assert.equal(await page.locator("#preset").inputValue(), "paper");
  assert.equal((await text("#row-nmci .trace")).trim(), "2.000");
  const omega = (await text("#row-nmci .omega")).split(",").map(Number);
  assert.deepEqual(omega, [0, 1]);
  assert.ok((await num("#row-ci .trace")) > 2.5);
  assert.match(await text("#blocks"), /\(2\)/);
  assert.match(await text("#sdp-status"), /status (Solved|AlmostSolved)/);
  assert.ok(Math.abs((await num("#row-sdp .trace")) - 2) < 1e-3);
  // The region of possible true fused covariances is drawn, with the five bounds.
  assert.ok((await page.locator("#layer-region path").count()) >= 100);
  for (const k of ["pa", "pb", "ci", "nmci", "sdp"]) assert.equal(await page.locator(`#layer-${k}`).count(), 1, k);
  await page.screenshot({ path: join(out, "explorer-paper.png"), fullPage: true });
});

test("choosing a preset and back restores the paper's numbers", async () => {
  await page.selectOption("#preset", "twoblock");
  await settle();
  assert.equal(await page.locator("#grid-pa input").count(), 16);
  assert.match(await text("#blocks"), /\(2\)/);
  await page.selectOption("#preset", "paper");
  await settle();
  assert.equal((await text("#row-nmci .trace")).trim(), "2.000");
});

test("editing P_a changes the numbers, and its mirror entry follows", async () => {
  const before = await text("#row-ci .trace");
  await cell("pa", 1, 1).fill("5");
  await settle();
  assert.notEqual(await text("#row-ci .trace"), before);
  await cell("pa", 1, 2).fill("0.5");
  await settle();
  assert.equal(await cell("pa", 2, 1).inputValue(), "0.5");
  assert.equal(await page.locator("#preset").inputValue(), "custom");
});

test("a non-PD matrix shows an inline error, keeps the last picture, and the page still responds", async () => {
  const lastTrace = await text("#row-ci .trace");
  await cell("pa", 1, 2).fill("10");
  await settle();
  assert.match(await text("#err-pa"), /P_a is not positive definite \(smallest eigenvalue -/);
  assert.equal(await text("#row-ci .trace"), lastTrace, "the last valid numbers stay");
  await cell("pb", 1, 1).fill("abc");
  assert.match(await text("#err-pb"), /"abc" is not a number/);
  assert.ok(await cell("pb", 1, 1).evaluate((e) => e.classList.contains("bad")));
  await cell("pb", 1, 1).fill("1");
  await cell("pa", 1, 2).fill("0");
  await settle();
  assert.equal(await text("#err-pa"), "");
  assert.equal(await text("#err-pb"), "");
  assert.notEqual(await text("#row-ci .trace"), lastTrace);
});

test("toggling a pattern cell changes the detected blocks", async () => {
  await page.selectOption("#preset", "paper");
  await settle();
  assert.match(await text("#blocks"), /nmCI blocks \(2\)/);
  await page.locator('#grid-pattern button[aria-label="P_ab[1,2]"]').click();
  await settle();
  assert.match(await text("#blocks"), /nmCI blocks \(1\)/);
  // One block: nmCI falls back to CI; the optimal bound is still below.
  assert.equal(await text("#row-nmci .trace"), await text("#row-ci .trace"));
  assert.ok((await num("#row-sdp .trace")) < (await num("#row-nmci .trace")));
  await page.screenshot({ path: join(out, "explorer-not-separable.png"), fullPage: true });
});

test("a URL hash restores the whole state", async () => {
  await page.selectOption("#preset", "twoblock");
  await settle();
  await page.selectOption("#view-j", "3");
  await cell("pb", 2, 2).fill("2.5");
  await settle();
  const url = page.url();
  const traces = await text("#table tbody");
  const other = await browser.newPage();
  other.on("pageerror", (e) => problems.push(`page error (second page): ${e.message}`));
  await other.goto(url);
  await other.waitForFunction(() => document.body.dataset.ready === "true", null, { timeout: 60_000 });
  assert.equal(await other.locator("#dim").inputValue(), "4");
  assert.equal(await other.locator("#view-j").inputValue(), "3");
  assert.equal(await other.locator('#grid-pb input[aria-label="P_b[2,2]"]').inputValue(), "2.5");
  assert.equal(await other.locator("#table tbody").innerText(), traces);
  await other.screenshot({ path: join(out, "explorer-twoblock-from-hash.png"), fullPage: true });
  await other.close();
});

test("dragging the P_a major-axis handle rotates and stretches P_a, and the grid follows", async () => {
  await page.selectOption("#preset", "paper");
  await settle();
  const svg = await page.locator("#plot").boundingBox();
  const unit = svg.width / 520; // viewBox → screen
  const attr = async (axis, name) => Number(await page.locator(`circle.handle[data-key="pa"][data-axis="${axis}"]`).getAttribute(name));
  // P_a = diag(3, 1): the major handle sits at (√3, 0), the minor one at (0, 1).
  const [x0, y0] = [await attr("minor", "cx"), await attr("major", "cy")];
  const scale = ((await attr("major", "cx")) - x0) / Math.sqrt(3);
  const screen = (x, y) => [svg.x + x * unit, svg.y + y * unit];
  const before = await text("#row-ci .trace");
  await page.mouse.move(...screen(x0 + Math.sqrt(3) * scale, y0));
  await page.mouse.down();
  for (let k = 1; k <= 8; k++) {
    const t = (k / 8) * (Math.PI / 2); // sweep to (0, 2): major axis 2, rotated by 90°
    const r = Math.sqrt(3) + (k / 8) * (2 - Math.sqrt(3));
    await page.mouse.move(...screen(x0 + r * Math.cos(t) * scale, y0 - r * Math.sin(t) * scale));
  }
  await page.mouse.up();
  await settle();
  const v = async (i, j) => Number(await cell("pa", i, j).inputValue());
  assert.ok(Math.abs((await v(1, 1)) - 1) < 0.02, `P_a[1,1] = ${await v(1, 1)}`);
  assert.ok(Math.abs((await v(2, 2)) - 4) < 0.05, `P_a[2,2] = ${await v(2, 2)}`);
  assert.ok(Math.abs(await v(1, 2)) < 0.05 && (await v(1, 2)) === (await v(2, 1)));
  assert.notEqual(await text("#row-ci .trace"), before);
  assert.equal(await page.locator("#preset").inputValue(), "custom");
});

test("the picture exports as SVG and the numbers as JSON", async () => {
  await page.selectOption("#preset", "paper");
  await settle();
  const [svgDownload] = await Promise.all([page.waitForEvent("download"), page.click("#export-svg")]);
  const svgPath = join(out, "explorer-paper.svg");
  await svgDownload.saveAs(svgPath);
  const svg = await readFile(svgPath, "utf8");
  assert.match(svg, /^<svg[^>]*xmlns="http:\/\/www.w3.org\/2000\/svg"/);
  assert.match(svg, /id="layer-nmci"/);
  assert.doesNotMatch(svg, /class="handle"/, "drag handles are not exported");
  const [jsonDownload] = await Promise.all([page.waitForEvent("download"), page.click("#export-json")]);
  const numbers = JSON.parse(await readFile(await jsonDownload.path(), "utf8"));
  assert.equal(numbers.nmci.trace, 2);
  assert.deepEqual(numbers.nmci.omega, [0, 1]);
  assert.equal(numbers.state.n, 2);
  assert.equal(numbers.region, undefined, "the bulky region is left out of the numbers");
});

test("the wasm package imports nothing from \"env\"", async () => {
  const bytes = await readFile(join(www, "pkg", "nmci_bg.wasm"));
  const imports = WebAssembly.Module.imports(new WebAssembly.Module(bytes));
  assert.deepEqual(imports.filter((i) => i.module === "env"), []);
  assert.doesNotMatch(await readFile(join(www, "pkg", "nmci.js"), "utf8"), /from\s+['"]env['"]/);
});

test("interaction cost: recompute after an edit (n = 2, 200 SDP samples, 300 region samples)", async () => {
  await page.selectOption("#preset", "paper");
  await settle();
  await page.evaluate(() => window.nmciStats.timings.splice(0));
  for (let k = 0; k < 40; k++) {
    await cell("pa", 1, 1).fill(String(3 + (k % 7) * 0.1));
    await settle();
  }
  const stats = await page.evaluate(() => ({ median: window.nmciStats.median(), count: window.nmciStats.timings.length, timings: window.nmciStats.timings }));
  assert.ok(stats.count >= 40, `${stats.count} timings`);
  assert.ok(Number.isFinite(stats.median));
  await writeFile(join(out, "interaction.json"), JSON.stringify({ ...stats, what: "edit → all rules + SDP (200 samples) + region (300) → rendered, headless Chromium" }, null, 2));
  console.log(`interaction cost: median ${stats.median.toFixed(1)} ms over ${stats.count} edits`);
});

test("no page errors or console errors along the way", () => {
  assert.deepEqual(problems, []);
});
