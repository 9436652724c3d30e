// End-to-end test of the explorer, as a person uses it: the page is served on 127.0.0.1 and
// driven in Debian's headless Chromium through playwright-core (no browser download).
// Needs the wasm package built into www/pkg (scripts/wasm.sh build). Writes screenshots and
// the measured interaction cost to test-output/e2e/.
import { test, before, after, beforeEach, afterEach } from "node:test";
import assert from "node:assert/strict";
import { readFile, mkdir, writeFile } from "node:fs/promises";
import { join } from "node:path";
import { execFileSync } from "node:child_process";
import { root, www, serveWww, launchChromium } from "./harness.mjs";

const out = join(root, "test-output", "e2e");

let server, base, chromium, browser;
// Each test gets a fresh page (`page`, opened on the paper's example), so one failure cannot
// leave state behind for the next; page errors and console errors of every page a test opens
// fail that test.
let page;
let problems = [];

before(async () => {
  await mkdir(out, { recursive: true });
  server = await serveWww();
  base = server.base;
  chromium = await launchChromium();
  browser = chromium.browser;
});

after(async () => {
  await chromium?.close();
  server?.close();
});

beforeEach(async () => {
  problems = [];
  page = await openPage(base);
});

afterEach(async () => {
  for (const p of browser.pages()) if (p !== chromium.page) await p.close();
  assert.deepEqual(problems, [], "page errors or console errors");
});

/** A new page at `url`, its errors collected in `problems`, once its first results are shown. */
async function openPage(url) {
  const p = await browser.newPage();
  p.on("pageerror", (e) => problems.push(`page error: ${e.message}`));
  p.on("console", (m) => m.type() === "error" && problems.push(`console error: ${m.text()}`));
  await p.goto(url);
  await p.waitForFunction(() => document.body.dataset.ready === "true", null, { timeout: 60_000 });
  return p;
}

async function settle() {
  await page.waitForFunction(() => document.body.dataset.ready === "true", null, { timeout: 60_000 });
}
const text = (sel) => page.locator(sel).innerText();
const num = async (sel) => Number((await text(sel)).trim());
/** The region's ellipses drawn: closed subpaths of the region layer's one path. */
/** `#rrggbb` → [r, g, b]. */
const hexRgb = (hex) => [1, 3, 5].map((i) => parseInt(hex.slice(i, i + 2), 16));
/** The page's registry entry of a rule (the wasm `rules()`, as www/rules.js reads it). */
const ruleOf = (name) => page.evaluate(async (n) => (await import("./rules.js")).RULE[n], name);
/** How many pixels of the canvas `sel` are exactly the colour `[r, g, b]` (opaque). */
const pixelsOf = (sel, [r, g, b]) =>
  page.locator(sel).evaluate((c, [r, g, b]) => {
    const d = c.getContext("2d").getImageData(0, 0, c.width, c.height).data;
    let n = 0;
    for (let i = 0; i < d.length; i += 4) if (d[i] === r && d[i + 1] === g && d[i + 2] === b && d[i + 3] === 255) n++;
    return n;
  }, [r, g, b]);
const regionEllipses = async () => ((await page.locator("#layer-region path").getAttribute("d")) ?? "").split("M").length - 1;
const cell = (key, i, j) => page.locator(`#grid-${key} input[aria-label="${key === "pa" ? "P_a" : "P_b"}[${i},${j}]"]`);

test("opens on the paper's example: nmCI trace 2.000, ω = [0, 1], CI looser", async () => {
  assert.equal(await page.locator("#preset").inputValue(), "paper");
  assert.equal((await text("#row-nmci .trace")).trim(), "2.000");
  // The estimates' rows (from wasm): P_a = diag(3, 1), P_b = diag(1, 4).
  assert.deepEqual([await text("#row-pa .trace"), await text("#row-pa .det"), await text("#row-pb .trace"), await text("#row-pb .det")].map((t) => t.trim()), ["4.000", "3.000", "5.000", "4.000"]);
  const omega = (await text("#row-nmci .omega")).split(",").map(Number);
  assert.deepEqual(omega, [0, 1]);
  assert.ok((await num("#row-ci .trace")) > 2.5);
  assert.match(await text("#blocks"), /\(2\)/);
  assert.match(await text("#sdp-status"), /status (Solved|AlmostSolved)/);
  assert.ok(Math.abs((await num("#row-sdp .trace")) - 2) < 1e-3);
  // The certified bracket: dual objective below, the best conservative rule (nmCI) above.
  assert.match(await text("#gap"), /lies in \[(1\.99999\d|2\.000000), 2\.000000\] \(both ends proven, every rounding accounted for: a Lagrangian bound from the SDP's duals below, the nmCI bound above\)/);
  assert.match(await text("#gap-verdict"), /^proven optimal to 10⁻⁶ \(relative\): the nmCI bound is within 10⁻⁶ of the robust optimum$/);
  // The region of possible true fused covariances is drawn, with the five bounds.
  assert.ok((await regionEllipses()) >= 100);
  for (const k of ["pa", "pb", "ci", "nmci", "sdp"]) assert.equal(await page.locator(`#layer-${k}`).count(), 1, k);
  // ICI, EI and naive fusion: in the table with what they are (not) guaranteed for, COIN per
  // rule over the drawn P' (naive fusion's > 1, flagged), their ellipses off until ticked.
  assert.match(await text("#row-ici"), /common information only/);
  assert.match(await text("#row-ei"), /not guaranteed conservative/);
  assert.match(await text("#row-naive"), /not guaranteed conservative/);
  assert.equal((await text("#row-naive .trace")).trim(), "1.550");
  const worstCoin = async (k) => Number((await text(`#row-${k} .coin`)).split(" ")[0]);
  assert.ok((await worstCoin("ci")) < 1 && (await worstCoin("nmci")) <= 1);
  assert.ok((await worstCoin("naive")) > 1);
  assert.equal(await page.locator("#row-naive .coin.neg").count(), 1);
  assert.equal(await page.locator("#layer-naive").count(), 0);
  await page.check('#legend input[data-layer="naive"]');
  await page.check('#legend input[data-layer="ici"]');
  assert.equal(await page.locator("#layer-naive").count(), 1);
  assert.equal(await page.locator("#layer-ici").count(), 1);
  await page.screenshot({ path: join(out, "explorer-paper.png"), fullPage: true });
  await page.uncheck('#legend input[data-layer="naive"]');
  await page.uncheck('#legend input[data-layer="ici"]');
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

test("the round-off preset keeps nmCI's blocks and says what was absorbed; coupling tol 0 shows the fall back to CI; a bad tolerance is refused inline", async () => {
  await page.selectOption("#preset", "roundoff");
  await settle();
  const { nmci } = await assertRulesMatchCli(page, "roundoff");
  assert.equal(nmci.structure.blocks.length, 2);
  assert.match(await text("#blocks"), /nmCI blocks \(2\)/);
  assert.match(await text("#structure-note"), /^structure: 2 near-zero couplings .* absorbed into a proven block-diagonal bound: 2 blocks instead of 1 from exact zeros/);
  assert.match(await text("#structure-note"), /nmCI's trace is \d\.\d\de-1\d above/);
  assert.ok((await num("#row-nmci .trace")) < (await num("#row-ci .trace")) - 0.01);
  assert.equal(await page.locator("#row-nmci .coin.neg").count(), 0);
  // The SDP solves the deflated problem block by block: the bracket, proven for the coupled
  // covariances at both ends, is the one of the same covariances without the couplings (the
  // two-block preset) to the digits shown.
  const bracket = async () => (await text("#gap")).match(/\[[^\]]*\]/)[0];
  const coupled = await bracket();
  await page.screenshot({ path: join(out, "explorer-roundoff.png"), fullPage: true });
  await page.selectOption("#preset", "twoblock");
  await settle();
  assert.equal(await bracket(), coupled);
  await page.selectOption("#preset", "roundoff");
  await settle();
  await page.fill("#coupling-tol", "0");
  await settle();
  await assertRulesMatchCli(page, "roundoff, coupling tol 0");
  assert.match(await text("#blocks"), /nmCI blocks \(1\)/);
  assert.equal(await text("#row-nmci .trace"), await text("#row-ci .trace"));
  assert.match(await text("#structure-note"), /keeps blocks merged: coupling_tol = [\d.]+e-13 would give 2 blocks/);
  await page.fill("#coupling-tol", "2");
  await settle();
  assert.match(await text("#err-settings"), /coupling_tol must be in \[0, 1\]/);
  await page.fill("#coupling-tol", "");
  await settle();
  assert.equal(await text("#err-settings"), "");
  // Declared blocks: agreeing ones give the same numbers (and the CLI's); each refusal is
  // shown beside the input it names, and the last valid result stays.
  await page.fill("#declared-blocks", "0 1 | 2 3");
  await settle();
  await assertRulesMatchCli(page, "roundoff, declared blocks");
  assert.match(await text("#blocks"), /nmCI blocks \(2\)/);
  for (const [typed, message] of [
    ["0 1 | 2", /state 3 is in no block/],
    ["0 1 | 1 2 3", /state 1 is in two blocks/],
    ["0 1 | x", /"x" is not a state index/],
    ["0 2 | 1 3", /pab_unknown\[0\]\[1\] is true, but states 0 and 1 are in declared blocks 0 and 1/],
  ]) {
    await page.fill("#declared-blocks", typed);
    await settle();
    assert.match(await text("#err-pattern"), message, typed);
  }
  // With a pattern that agrees, the covariances still link the declared blocks: refused,
  // naming the strongest entry, beside P_b.
  await page.click('button[data-pattern="diagonal"]');
  await settle();
  assert.match(await text("#err-pb"), /pb\[2\]\[3\] = 1 couples blocks 0 and 1/);
  await page.fill("#declared-blocks", "");
  await settle();
  assert.equal(await text("#err-pattern"), "");
  assert.equal(await text("#err-pb"), "");
  await page.selectOption("#preset", "paper");
  await settle();
});

/** The CLI's response to a fusion request (the same crate, natively). */
function cli(request) {
  const out = execFileSync("cargo", ["run", "--quiet", "--bin", "nmci", "--", "fuse"], { cwd: root, input: JSON.stringify(request) });
  return JSON.parse(out.toString());
}
/** The page's rounding of a table number. */
const three = (v) => v.toFixed(3);

test("editing P_a changes the numbers to the CLI's for the same inputs, and its mirror entry follows", async () => {
  const pb = [[1, 0], [0, 4]];
  const diagonal = [[true, false], [false, true]];
  await cell("pa", 1, 1).fill("5");
  await settle();
  for (const method of ["ci", "nmci", "ici", "naive"]) {
    const r = cli({ pa: [[5, 0], [0, 1]], pb, pab_unknown: diagonal, method });
    assert.equal((await text(`#row-${method} .trace`)).trim(), three(r.trace), method);
  }
  await cell("pa", 1, 2).fill("0.5");
  await settle();
  assert.equal(await cell("pa", 2, 1).inputValue(), "0.5");
  assert.equal(await page.locator("#preset").inputValue(), "custom");
  for (const method of ["ci", "nmci"]) {
    const r = cli({ pa: [[5, 0.5], [0.5, 1]], pb, pab_unknown: diagonal, method });
    assert.equal((await text(`#row-${method} .trace`)).trim(), three(r.trace), method);
    const omega = (await text(`#row-${method} .omega`)).split(",").map((v) => Number(v));
    assert.equal(omega.length, r.omega.length, method);
    omega.forEach((w, k) => assert.ok(Math.abs(w - r.omega[k]) <= 5e-4, `${method} ω ${omega} vs ${r.omega}`));
  }
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
  await cell("pa", 1, 2).fill("0.5");
  await settle();
  assert.equal(await text("#err-pa"), "");
  assert.equal(await text("#err-pb"), "");
  assert.notEqual(await text("#row-ci .trace"), lastTrace);
  await assertRulesMatchCli(page, "after the errors");
});

test("toggling a pattern cell changes the detected blocks", async () => {
  assert.match(await text("#blocks"), /nmCI blocks \(2\)/);
  await page.locator('#grid-pattern button[aria-label="P_ab[1,2]"]').click();
  await settle();
  assert.match(await text("#blocks"), /nmCI blocks \(1\)/);
  // One block: nmCI falls back to CI; the optimal bound is still below, and the certified
  // rule — proven conservative — recovers most of it and closes the bracket from above.
  assert.equal(await text("#row-nmci .trace"), await text("#row-ci .trace"));
  assert.ok((await num("#row-sdp .trace")) < (await num("#row-nmci .trace")));
  assert.ok((await num("#row-certified .trace")) < (await num("#row-nmci .trace")) - 0.01);
  assert.equal(await page.getAttribute("#row-certified", "title"), "certified: conservative");
  assert.match(await text("#certified-status"), /% below the best of CI and nmCI, proven to dominate/);
  assert.match(await text("#gap"), /duals below, the certified bound above/);
  // Two states: the certificate is level 1 on sectors of directions, and the page says which.
  assert.match(await text("#gap-verdict"), /^(proven optimal to 10⁻⁶ \(relative\): the certified bound \(certificate level 1 on 24 sectors\) is within|open: the robust optimum lies between the ends \(certificate level 1 on 24 sectors\))/);
  assert.match(await text("#certified-status"), /\(certificate level 1 on 24 sectors, status/);
  assert.equal(await page.locator("#row-certified .coin.neg").count(), 0);
  assert.equal(await page.locator("#layer-certified").count(), 1);
  await page.screenshot({ path: join(out, "explorer-not-separable.png"), fullPage: true });
});

test("a fully unknown 4-D P_ab defeats the rejection sampler; hit-and-run gives the SDP and its certified gap", async () => {
  await page.selectOption("#preset", "twoblock");
  await settle();
  await page.click('button[data-pattern="full"]');
  await settle();
  // The default sampler (auto) saw it coming and took hit-and-run.
  assert.match(await text("#sdp-status"), /auto: hit-and-run sampler \(no rejections\) — the rejection sampler's pilot accepted \d of 2000 proposals \([\d.]+ %\), too few for 200 samples within its budget/);
  await page.selectOption("#sampler", "rejection");
  await settle();
  assert.match(await text("#row-sdp"), /not available: the rejection sampler accepted only \d+ of 200/);
  await page.selectOption("#sampler", "hit_and_run");
  await settle();
  assert.match(await text("#sdp-status"), /status (Solved|AlmostSolved).*hit-and-run sampler/);
  assert.match(await text("#gap"), /duals below, the (nmCI|CI|certified) bound above/);
  assert.match(await text("#gap-verdict"), /^open: /);
  assert.match(await text("#region-status"), /300 admissible P\s*ab drawn \(hit-and-run sampler \(no rejections\)\)/);
  // The sampler is part of the shareable state.
  assert.match(decodeURIComponent(await page.evaluate(() => location.hash)), /"sampler":"hit_and_run"/);
  await page.screenshot({ path: join(out, "explorer-hit-and-run.png"), fullPage: true });
});

test("at three states a second stage closes the bracket the sampled SDP leaves open: the cutting planes' own rule, proven; an edit abandons it", async () => {
  // P_ab's anti-diagonal known zero: one block, so nmCI is CI; the sampled SDP's lower end
  // and the level-2 certificate leave the bracket open by percent.
  const state = {
    n: 3, pattern: ["110", "101", "011"], view: [0, 1],
    pa: [[2.573, 1.484, 0.916], [1.484, 1.767, 0.987], [0.916, 0.987, 3.586]],
    pb: [[2.645, -0.105, 1.613], [-0.105, 4.357, -0.592], [1.613, -0.592, 1.562]],
  };
  page = await openPage(`${base}#${encodeURIComponent(JSON.stringify(state))}`);
  assert.match(await text("#gap"), /duals below, the certified bound above\): gap [\d.e-]+ absolute, [\d.]+ % relative — open: the robust optimum lies between the ends \(certificate level 2\)$/);
  assert.match(await text("#proof-status"), /^second stage: the cutting planes are closing the bracket \(up to 30 s\)…$/);
  const proven = async () => {
    await page.waitForFunction(() => document.body.dataset.proving === "false", null, { timeout: 120_000 });
    assert.match(await text("#gap"), /\(both ends proven, every rounding accounted for: a Lagrangian bound from the cutting planes' duals below, the cutting planes' own rule \(proven on \d+ cones of directions\) above\)/);
    assert.match(await text("#gap-verdict"), /^proven optimal to 10⁻⁶ \(relative\): the cutting planes' own rule \(proven on \d+ cones of directions\) is within 10⁻⁶ of the robust optimum$/);
    assert.match(await text("#proof-status"), /^second stage: the cutting planes \(\d+ iterations, stopped by converged\) narrowed the bracket [\d.e+]+ times; their gains with the bound proven for them \(tr P̄ [\d.]+, drawn in the picture\) are in the JSON export$/);
    assert.equal(await page.locator("#layer-proven").count(), 1, "the proven rule's ellipse");
  };
  assert.equal(await page.locator("#layer-proven").count(), 0, "no proven rule while the proof runs");
  await proven();
  await page.screenshot({ path: join(out, "explorer-second-stage.png"), fullPage: true });
  // The export holds the proof: the gains, and the bound proven for them within the bracket.
  const [download] = await Promise.all([page.waitForEvent("download"), page.click("#export-json")]);
  const { second_stage: proof } = JSON.parse(await readFile(await download.path(), "utf8"));
  assert.ok(proof.own_rule_proven && proof.closed, JSON.stringify(proof));
  assert.equal(proof.rule.p.length, 3);
  assert.ok(proof.rule.trace <= proof.upper && proof.rule.trace >= proof.lower, `${proof.rule.trace} ${proof.upper}`);
  proof.rule.ka.forEach((row, i) => row.forEach((k, j) => assert.ok(Math.abs(k + proof.rule.kb[i][j] - (i === j)) <= 1e-15)));
  // The proof's bracket lies within the first one (both proven, so they must overlap).
  const ends = (t) => t.match(/\[([\d.]+), ([\d.]+)\]/).slice(1).map(Number);
  const [lo, hi] = ends(await text("#gap"));
  assert.ok(hi - lo <= 2e-6 * hi && lo <= hi, `${lo} ${hi}`);
  // Two edits in a row: the first one's proof is abandoned, the second one's shown.
  const abandoned = await page.evaluate(() => window.nmciStats.proofsAbandoned);
  await cell("pb", 3, 3).fill("1.6");
  await page.waitForFunction(() => document.body.dataset.proving === "true", null, { timeout: 60_000 });
  await cell("pb", 3, 3).fill("1.562");
  await settle();
  assert.ok((await page.evaluate(() => window.nmciStats.proofsAbandoned)) > abandoned, "no proof was abandoned");
  await proven();
  assert.deepEqual(ends(await text("#gap")), [lo, hi]);
});

test("an edit during a long solve abandons it: a fresh worker computes the newest state", async () => {
  await page.selectOption("#preset", "twoblock");
  await settle();
  await page.click('button[data-pattern="full"]');
  await settle();
  await page.selectOption("#sampler", "hit_and_run");
  await settle();
  const abandoned = await page.evaluate(() => window.nmciStats.abandoned);
  await page.fill("#samples", "4000"); // a 4-D SDP over 4000 samples: seconds in the worker
  await page.waitForTimeout(150);
  await page.fill("#samples", "120"); // newer: the running solve is stale
  await settle();
  assert.ok((await page.evaluate(() => window.nmciStats.abandoned)) > abandoned, "no solve was abandoned");
  assert.match(await text("#sdp-status"), /final working set of 120 samples/);
});

test("a URL hash restores the whole state", async () => {
  await page.selectOption("#preset", "twoblock");
  await settle();
  await page.selectOption("#view-j", "3");
  await cell("pb", 2, 2).fill("2.5");
  await settle();
  const url = page.url();
  const traces = await text("#table tbody");
  const other = await openPage(url);
  assert.equal(await other.locator("#dim").inputValue(), "4");
  assert.equal(await other.locator("#view-j").inputValue(), "3");
  assert.equal(await other.locator('#grid-pb input[aria-label="P_b[2,2]"]').inputValue(), "2.5");
  assert.equal(await other.locator("#table tbody").innerText(), traces);
  await other.screenshot({ path: join(out, "explorer-twoblock-from-hash.png"), fullPage: true });
  await other.close();
  // The hash of an edit is written once its analysis is done (not while the worker computes),
  // and the share button writes it at once: an edit and a click in one task, before any
  // result can arrive.
  const during = await page.evaluate(() => {
    const input = document.querySelector('#grid-pb input[aria-label="P_b[2,2]"]');
    input.value = "2.75";
    input.dispatchEvent(new Event("input", { bubbles: true }));
    const before = decodeURIComponent(location.hash);
    document.querySelector("#share").click();
    return { ready: document.body.dataset.ready, before, after: decodeURIComponent(location.hash) };
  });
  assert.equal(during.ready, "false", "the edit's analysis is in flight");
  assert.match(during.before, /\[-0\.3,2\.5,0,0\]/, "no hash write while the worker computes");
  assert.match(during.after, /\[-0\.3,2\.75,0,0\]/, "share writes the edit's state");
  await settle();
  assert.match(decodeURIComponent(await page.evaluate(() => location.hash)), /\[-0\.3,2\.75,0,0\]/);
  // A refused clipboard is said, not silent.
  await page.evaluate(() => Object.defineProperty(navigator, "clipboard", { configurable: true, value: { writeText: () => Promise.reject(new DOMException("denied", "NotAllowedError")) } }));
  await page.click("#share");
  await page.waitForFunction(() => /could not be copied/.test(document.querySelector("#err-general").textContent));
  await page.evaluate(() => delete navigator.clipboard);
});

test("a malformed or out-of-range URL hash says so: the paper's example, or the defaults for bad settings, named", async () => {
  const cases = [
    ["#%7Bnot-json", "the link's state could not be read"],
    [`#${encodeURIComponent(JSON.stringify({ n: 9, pa: [[1]], pb: [[1]], pattern: ["1"] }))}`, "the link's state is incomplete or out of range"],
    [`#${encodeURIComponent(JSON.stringify({ n: 2, pa: [[1, 0], [0, 1]], pb: [[1, 0], [0, "x"]], pattern: ["10", "01"] }))}`, "the link's state is incomplete or out of range"],
  ];
  // Readable, with optional settings out of range: loaded, the defaults used and named.
  const good = { n: 2, pa: [[3, 0], [0, 1]], pb: [[1, 0], [0, 4]], pattern: ["10", "01"], samples: 0, sampler: "gibbs", preset: "paper" };
  {
    const other = await openPage(`${base}#${encodeURIComponent(JSON.stringify(good))}`);
    assert.equal(await other.locator("#err-link").innerText(), "the link's samples, sampler were out of range; the defaults are used");
    assert.equal(await other.locator("#samples").inputValue(), "200");
    assert.equal((await other.locator("#row-nmci .trace").innerText()).trim(), "2.000");
    await other.close();
  }
  for (const [hash, message] of cases) {
    const other = await openPage(base + hash);
    // The reason stays after the first results arrive (they clear the other messages).
    assert.equal(await other.locator("#err-link").innerText(), message, hash);
    assert.equal(await other.locator("#preset").inputValue(), "paper");
    assert.equal((await other.locator("#row-nmci .trace").innerText()).trim(), "2.000");
    await other.close();
  }
});

test("dragging the P_a major-axis handle rotates and stretches P_a, and the grid follows", async () => {
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
  const [svgDownload] = await Promise.all([page.waitForEvent("download"), page.click("#export-svg")]);
  const svgPath = join(out, "explorer-paper.svg");
  await svgDownload.saveAs(svgPath);
  const svg = await readFile(svgPath, "utf8");
  assert.match(svg, /^<svg[^>]*xmlns="http:\/\/www.w3.org\/2000\/svg"/);
  assert.match(svg, /id="layer-nmci"/);
  assert.doesNotMatch(svg, /class="handle"/, "drag handles are not exported");
  // A title naming the matrices, and a legend line per layer drawn.
  assert.match(svg, /P_a = \[\[3, 0\], \[0, 1\]\], P_b = \[\[1, 0\], \[0, 4\]\]/);
  assert.match(svg, /<title>nmci: [^<]*nmCI/);
  const drawn = (svg.match(/id="layer-/g) ?? []).length;
  const legend = [...svg.matchAll(/<line [^>]*x1="14"/g)].length;
  assert.equal(legend, drawn, "one legend line per layer drawn");
  const [jsonDownload] = await Promise.all([page.waitForEvent("download"), page.click("#export-json")]);
  const numbers = JSON.parse(await readFile(await jsonDownload.path(), "utf8"));
  const nmci = numbers.rules.find((r) => r.method === "nmci").response;
  assert.equal(nmci.trace, 2);
  assert.deepEqual(nmci.omega, [0, 1]);
  assert.equal(numbers.state.n, 2);
  assert.equal(numbers.region, undefined, "the bulky region is left out of the numbers");
});

test("the wasm package imports nothing from \"env\"", async () => {
  const bytes = await readFile(join(www, "pkg", "nmci_bg.wasm"));
  const imports = WebAssembly.Module.imports(new WebAssembly.Module(bytes));
  assert.deepEqual(imports.filter((i) => i.module === "env"), []);
  assert.doesNotMatch(await readFile(join(www, "pkg", "nmci.js"), "utf8"), /from\s+['"]env['"]/);
});

/** The explorer state the page holds (read from its URL hash), as a fusion request. */
async function pageRequest(p, method) {
  const state = JSON.parse(decodeURIComponent(await p.evaluate(() => location.hash.slice(1))));
  const tol = state.coupling_tol === undefined ? {} : { coupling_tol: state.coupling_tol };
  const blocks = state.blocks === undefined ? {} : { blocks: state.blocks };
  return { pa: state.pa, pb: state.pb, pab_unknown: state.pattern.map((row) => [...row].map((c) => c === "1")), criterion: state.criterion, method, ...tol, ...blocks };
}
/** The page's CI and nmCI rows and nmCI's blocks equal the CLI's for the page's own state. */
async function assertRulesMatchCli(p, what) {
  const nmci = cli(await pageRequest(p, "nmci"));
  const ci = cli(await pageRequest(p, "ci"));
  assert.equal((await p.locator("#row-ci .trace").innerText()).trim(), three(ci.trace), `${what}: CI`);
  assert.equal((await p.locator("#row-nmci .trace").innerText()).trim(), three(nmci.trace), `${what}: nmCI`);
  const blocks = nmci.blocks.map((b) => `{${b.map((x) => "x" + (x + 1)).join(", ")}}`);
  const shown = (await p.locator("#blocks").innerText()).match(/\{[^}]*\}/g);
  assert.deepEqual(shown, blocks, `${what}: blocks`);
  return { ci, nmci };
}

/**
 * The interaction cost: `count` edits (`edit(k)` makes and checks edit `k`), each recomputed
 * once (asserted); the round-trip times (and the wasm call's) go to `test-output/e2e/<file>` —
 * a measurement for docs/development.md, not an assertion.
 */
async function measureEdits(count, edit, file, label, what) {
  await page.evaluate(() => { window.nmciStats.timings.splice(0); window.nmciStats.computeTimings.splice(0); });
  const runs0 = await page.evaluate(() => window.nmciStats.runs);
  for (let k = 0; k < count; k++) await edit(k);
  const stats = await page.evaluate(() => ({ median: window.nmciStats.median(), compute_median: window.nmciStats.computeMedian(), count: window.nmciStats.timings.length, runs: window.nmciStats.runs, timings: window.nmciStats.timings }));
  assert.equal(stats.runs - runs0, count, "one recompute per edit");
  assert.equal(stats.count, count);
  assert.ok(stats.timings.every((t) => Number.isFinite(t) && t > 0), JSON.stringify(stats.timings));
  await writeFile(join(out, file), JSON.stringify({ ...stats, what }, null, 2));
  console.log(`${label}: median ${stats.median.toFixed(1)} ms over ${stats.count} edits (wasm explore ${stats.compute_median.toFixed(1)} ms)`);
}

test("interaction cost: each of 40 edits is recomputed once, to the CLI's numbers (n = 2, 200 SDP samples, 300 region samples)", async () => {
  const values = ["3", "3.1", "3.2", "3.3", "3.4", "3.5", "3.6"];
  const expected = values.map((v) => three(cli({ pa: [[Number(v), 0], [0, 1]], pb: [[1, 0], [0, 4]], pab_unknown: [[true, false], [false, true]], method: "ci" }).trace));
  await measureEdits(40, async (k) => {
    // 3.1 … 3.6 in turn: never the value already shown (an unchanged input is not an edit).
    const v = 1 + (k % 6);
    await cell("pa", 1, 1).fill(values[v]);
    await settle();
    assert.equal((await text("#row-ci .trace")).trim(), expected[v], `edit ${k}`);
    assert.equal((await text("#row-nmci .trace")).trim(), "2.000", `edit ${k}`);
  }, "interaction.json", "interaction cost", "edit → all rules + SDP (200 samples) + region (300) → rendered, headless Chromium; compute_median: the wasm explore call alone");
});

test("an ellipse drawn is the 1σ ellipse of its covariance, every one in the same direction (the region's union fill)", async () => {
  const covariances = [[[3, 0], [0, 1]], [[1, 0], [0, 4]], [[2, 1.2], [1.2, 1]], [[1, -0.9], [-0.9, 1]], [[1, 0.95], [0.95, 1]], [[0.5, 0.1], [0.1, 2.5]]];
  const results = await page.evaluate(async (covariances) => {
    const { ellipsePath } = await import("./plot.js");
    const svg = document.createElementNS("http://www.w3.org/2000/svg", "svg");
    document.body.appendChild(svg);
    // A similarity with the y axis flipped, as the page's frames are, and an offset centre.
    const [cx, cy, scale, ox, oy] = [400, 380, 120, 0.5, 0.25];
    const toPx = (x, y) => [cx + (ox + x) * scale, cy - (oy + y) * scale];
    const out = covariances.map(([[a, b], [, d]]) => {
      const path = document.createElementNS("http://www.w3.org/2000/svg", "path");
      path.setAttribute("d", ellipsePath([[a, b], [b, d]], toPx));
      svg.appendChild(path);
      // Along 48 directions e, the ellipse {u : uᵀP⁻¹u = 1} is at radius 1/√(eᵀP⁻¹e):
      // 1 % inside it must be in the path's fill, 1 % outside must not.
      const det = a * d - b * b;
      const wrong = [];
      for (let k = 0; k < 48; k++) {
        const phi = (2 * Math.PI * k) / 48;
        const [e1, e2] = [Math.cos(phi), Math.sin(phi)];
        const r = 1 / Math.sqrt((d * e1 * e1 - 2 * b * e1 * e2 + a * e2 * e2) / det);
        for (const [f, inside] of [[0.99, true], [1.01, false]]) {
          const [px, py] = toPx(f * r * e1, f * r * e2);
          if (path.isPointInFill(new DOMPoint(px, py)) !== inside) wrong.push([k, f]);
        }
      }
      // The direction the path is drawn in: the sign of the signed area of points along it.
      const length = path.getTotalLength();
      let area = 0;
      let prev = path.getPointAtLength(0);
      for (let k = 1; k <= 48; k++) {
        const p = path.getPointAtLength((length * k) / 48);
        area += prev.x * p.y - p.x * prev.y;
        prev = p;
      }
      return { wrong, direction: Math.sign(area) };
    });
    svg.remove();
    return out;
  }, covariances);
  results.forEach((r, k) => assert.deepEqual(r.wrong, [], `covariance ${k}: directions (index, factor) on the wrong side`));
  assert.equal(new Set(results.map((r) => r.direction)).size, 1, `directions ${results.map((r) => r.direction)}`);
});

test("interaction cost at n = 4: 10 edits of the two-block preset (each cross block wholly unknown: CI's bound, proven without a solve), then 10 with one known zero in each (a 24-sector proof of the edited block, the other's from the memo), each recomputed once, to the CLI's numbers", async () => {
  await page.selectOption("#preset", "twoblock");
  await settle();
  assert.equal(await page.locator("#dim").inputValue(), "4");
  // P_a[1,1] = 3 in the preset: `value(k)` for edit k, never the value already shown.
  let value = (k) => `3.${1 + (k % 5)}`;
  const edits = async (k) => {
    await cell("pa", 1, 1).fill(value(k));
    await settle();
    await assertRulesMatchCli(page, `edit ${k}`);
    assert.match((await text("#row-certified .trace")).trim(), /^\d+\.\d{3}$/, `edit ${k}: the certified rule is shown`);
  };
  await measureEdits(10, edits, "interaction-n4.json", "interaction cost at n = 4", "n = 4, two 2 × 2 blocks, each cross block wholly unknown: edit → all rules (the certified rule: CI's proven bound on both blocks, no solve) + SDP (200 samples) + region (300) → rendered, headless Chromium; compute_median: the wasm explore call alone");
  // The same covariances with P_ab[2,1] and P_ab[4,3] known zero: still two blocks, each
  // partially known, so the certified rule solves a 24-sector program on each.
  for (const label of ["P_ab[2,1]", "P_ab[4,3]"]) {
    await page.locator(`#grid-pattern button[aria-label="${label}"]`).click();
    await settle();
  }
  assert.match(await text("#blocks"), /nmCI blocks \(2\)/);
  assert.match(await text("#certified-status"), /level 1 on 24 sectors, status \w+, [1-9]\d* iterations/);
  // A value not seen before at every edit (3.11 … 3.20): block 1's proof is solved each time,
  // block 2's comes from the worker's memo of certified blocks (an edit, not a revisit).
  value = (k) => `3.${11 + k}`;
  await measureEdits(10, edits, "interaction-n4-one-zero.json", "interaction cost at n = 4, one known zero per block", "n = 4, two 2 × 2 blocks, one known zero in each cross block: edit of block 1 to a new value → all rules (the certified rule: block 1's 24-sector proof solved, block 2's from the worker's memo) + SDP (200 samples) + region (300) → rendered, headless Chromium; compute_median: the wasm explore call alone");
});

test("a panic in the worker is reported, the worker replaced, and the next edit computed", async () => {
  const before = await text("#row-ci .trace");
  await page.evaluate(() => window.nmciStats.panicForTest("forced by the end-to-end test"));
  await settle();
  assert.match(await text("#err-general"), /^the computation crashed \(panicked at src\/wasm\.rs:\d+:\d+: forced by the end-to-end test\); its worker was replaced; the numbers shown are of the last state computed$/);
  assert.equal(await page.evaluate(() => window.nmciStats.crashes), 1);
  assert.equal(await text("#row-ci .trace"), before, "the last numbers stay");
  await page.screenshot({ path: join(out, "explorer-crash.png") });
  await cell("pa", 1, 1).fill("5");
  await settle();
  assert.equal(await text("#err-general"), "");
  await assertRulesMatchCli(page, "after the crash");
  // Three failures in a row (nothing computed between them): no worker is respawned in a
  // loop; the next edit starts one.
  for (let k = 1; k <= 3; k++) {
    await page.evaluate(() => window.nmciStats.panicForTest("forced again"));
    await settle();
  }
  assert.match(await text("#err-general"), /forced again\); 3 failures in a row: no new worker until the next edit; the numbers shown are of the last state computed$/);
  await cell("pa", 1, 1).fill("4");
  await settle();
  assert.equal(await text("#err-general"), "");
  await assertRulesMatchCli(page, "after three crashes");
});

/** The default sampler (auto) gave the SDP its samples and drew the region: both drawn. */
async function assertOptimalAndRegionDrawn(what) {
  assert.match(await text("#sdp-status"), /status (Solved|AlmostSolved).* auto: (rejection|hit-and-run) sampler/, what);
  assert.match(await text("#region-status"), /300 admissible P\s*ab drawn \(auto: (rejection|hit-and-run) sampler/, what);
  assert.equal(await page.locator("#layer-sdp").count(), 1, what);
  assert.ok((await regionEllipses()) >= 100, what);
}

test("every preset with every pattern preset shows the CLI's CI, nmCI and blocks", async () => {
  for (const preset of ["paper", "correlated", "twoblock", "six"]) {
    await page.selectOption("#preset", preset);
    await settle();
    await assertRulesMatchCli(page, preset);
    for (const pattern of ["full", "diagonal", "block", "chain"]) {
      await page.click(`button[data-pattern="${pattern}"]`);
      await settle();
      const what = `${preset}, ${pattern}`;
      const { ci, nmci } = await assertRulesMatchCli(page, what);
      const n = ci.p.length;
      // What each pattern preset means for nmCI: one block (nmCI is CI) for the fully
      // unknown and the chain patterns; for the diagonal and block-diagonal ones, the blocks
      // P_a and P_b already have (paper: diagonal; correlated: full; the 4-D and 6-D presets:
      // 2×2 blocks) — the block-diagonal preset pairs the states of the diagonal paper example.
      const expected = { full: 1, chain: 1, diagonal: { paper: 2, correlated: 1, twoblock: 2, six: 3 }[preset], block: { paper: 1, correlated: 1, twoblock: 2, six: 3 }[preset] }[pattern];
      assert.equal(nmci.blocks.length, expected, what);
      assert.equal(await page.locator("#grid-pattern button").count(), n * n, what);
      assert.equal(await text("#err-general"), "", what);
      await assertOptimalAndRegionDrawn(what);
    }
  }
});

test("changing n resizes the grids and the view, keeps the top-left entries, and shows the CLI's numbers", async () => {
  for (const n of [3, 5, 6, 2]) {
    await page.selectOption("#dim", String(n));
    await settle();
    assert.equal(await page.locator("#grid-pa input").count(), n * n, `n = ${n}`);
    assert.equal(await page.locator("#grid-pb input").count(), n * n, `n = ${n}`);
    assert.equal(await page.locator("#grid-pattern button").count(), n * n, `n = ${n}`);
    assert.equal(await page.locator("#view-j option").count(), n, `n = ${n}`);
    assert.equal(await cell("pa", 1, 1).inputValue(), "3");
    assert.equal(await cell("pb", 2, 2).inputValue(), "4");
    const { nmci } = await assertRulesMatchCli(page, `n = ${n}`);
    // The paper's P_a, P_b extended with identities and a diagonal pattern: nmCI takes the
    // smaller variance of each state, so its trace is n.
    assert.ok(Math.abs(nmci.trace - n) <= 1e-12 * n, `n = ${n}: ${nmci.trace}`);
    // The default sampler draws the optimal ellipse and the region at this n, for the
    // diagonal pattern and a fully unknown one (where the rejection sampler dies from n = 4).
    await assertOptimalAndRegionDrawn(`n = ${n}, diagonal`);
    await page.click('button[data-pattern="full"]');
    await settle();
    await assertRulesMatchCli(page, `n = ${n}, fully unknown`);
    await assertOptimalAndRegionDrawn(`n = ${n}, fully unknown`);
    await page.click('button[data-pattern="diagonal"]');
    await settle();
  }
  assert.equal(await page.locator("#preset").inputValue(), "custom");
  assert.equal((await text("#row-nmci .trace")).trim(), "2.000");
});

test("the study tab runs a short study live and shows nmCI tighter than CI", async () => {
  await page.click("#tab-study");
  assert.equal(await page.locator("#explorer").isVisible(), false);
  assert.equal(await page.locator("#study").isVisible(), true);
  await page.fill("#study-runs", "2");
  await page.fill("#study-steps", "80");
  await page.fill("#study-seed", "4");
  // Every progress line shown, to see what happened side by side.
  await page.evaluate(() => {
    window.studyProgress = [];
    new MutationObserver(() => window.studyProgress.push(document.querySelector("#study-progress").textContent)).observe(document.querySelector("#study-progress"), { childList: true, characterData: true, subtree: true });
  });
  // The workers the page starts for the study (the first study of this page: none exists yet).
  const studyWorkers = [];
  const onWorker = (worker) => studyWorkers.push(new URL(worker.url()).pathname.split("/").pop());
  page.on("worker", onWorker);
  await page.click("#study-start");
  // Live: a view arrives before the end (progress text shows a step of the two runs, which
  // advance together).
  await page.waitForFunction(() => /^2 runs, step \d+ of 80/.test(document.querySelector("#study-progress").textContent), null, { timeout: 60_000 });
  await page.waitForFunction(() => document.body.dataset.study === "done", null, { timeout: 120_000 });
  assert.match(await text("#study-progress"), /^done: 2 runs × 80 steps/);
  page.off("worker", onWorker);
  // With the exact COIN on (the default), four: the rules' two and the COIN's two.
  assert.deepEqual(studyWorkers.filter((f) => f.startsWith("study-")).sort(), ["study-coin-part-worker.js", "study-coin-worker.js", "study-rules-worker.js", "study-worker.js"]);
  // The rules ran in two workers (www/study-rules-worker.js beside www/study-worker.js):
  // the numbers behind the table are those of one wasm `Study` running every rule, bit for
  // bit.
  // So is the exact COIN, its estimators shared between two more workers
  // (www/study-coin-part-worker.js beside www/study-coin-worker.js).
  const shown = JSON.parse(await page.getAttribute("#study-table", "data-report"));
  const shownCoin = JSON.parse(await page.getAttribute("#study-table", "data-coin"));
  const alone = await page.evaluate(async () => {
    const { Study, StudyCoin } = await import("./pkg/nmci.js");
    const config = { runs: 2, steps: 80, seed: 4, coin: false };
    const study = new Study(config);
    while (!study.advance(40));
    const report = study.view().report;
    study.free();
    const coin = new StudyCoin(config);
    while (!coin.advance(100));
    const estimators = coin.view().estimators;
    coin.free();
    return { report, estimators };
  });
  assert.deepEqual(shown, alone.report);
  assert.equal(shownCoin.length, 5);
  assert.deepEqual(shownCoin, alone.estimators);
  // The exact COIN runs in its own workers beside the runs, not after them: it had work done
  // while a run was still in progress.
  const progress = await page.evaluate(() => window.studyProgress);
  assert.ok(progress.some((p) => /^2 runs, step \d+ of 80; exact COIN [1-9]\d*%: step \d+ of 80/.test(p)), progress.join("\n"));
  const rows = await page.evaluate(() => Object.fromEntries([...document.querySelectorAll("#study-table tbody tr")].map((tr) => [tr.dataset.estimator, [...tr.children].map((td) => td.textContent)])));
  assert.deepEqual(Object.keys(rows), ["central", "ci", "nmci", "naive", "ici"]);
  assert.match(rows.naive[0], /not guaranteed conservative/);
  assert.match(rows.ici[0], /common information only/);
  // Exact COIN (mean, max): the centralized KF is exact, CI and nmCI conservative, naive
  // fusion overconfident (its row flagged).
  const coin = (k, c) => Number(rows[k][c]);
  assert.equal(rows.central[5], "1.000");
  assert.equal(rows.central[6], "1.000");
  for (const k of ["ci", "nmci"]) assert.ok(coin(k, 5) < 1 && coin(k, 6) <= 1, `${k} COIN ${rows[k].slice(5)}`);
  assert.ok(coin("naive", 6) > 1, `naive COIN ${rows.naive.slice(5)}`);
  assert.deepEqual(await page.locator("#study-table tr.warn").evaluateAll((trs) => trs.map((tr) => tr.dataset.estimator)), ["naive"]);
  const rmse = (k) => Number(rows[k][1]);
  const twoSigma = (k) => Number(rows[k][2]);
  assert.ok(rmse("nmci") < rmse("ci"), `nmCI RMSE ${rmse("nmci")} vs CI ${rmse("ci")}`);
  assert.ok(twoSigma("nmci") < twoSigma("ci"));
  assert.ok(rmse("central") < rmse("nmci"));
  assert.match(await text("#study-omega"), /nmCI vs CI: RMSE -\d+%/);
  const ci = await page.evaluate(async () => (await import("./pkg/nmci.js")).study_estimators().find((e) => e.name === "ci"));
  const CI_RGB = hexRgb(ci.colour);
  // Four charts drawn by the wasm module on canvases (src/chart/, the code of `nmci track`'s
  // SVG files): every line over the whole run, and CI's colour on the canvas.
  for (const id of ["#study-nees", "#study-rmse", "#study-omega-plot", "#study-coin-plot"]) {
    const lengths = (await page.getAttribute(id, "data-points")).split(",").map(Number);
    assert.ok(lengths.length >= 3 && lengths.every((n) => n === 80), `${id}: ${lengths}`);
    const labels = JSON.parse(await page.getAttribute(id, "data-labels"));
    assert.ok(labels.some((l) => l !== null && l.startsWith(ci.short_label)), `${id}: no CI line in ${labels}`);
    assert.ok((await pixelsOf(id, CI_RGB)) > 50, `${id}: CI's colour not drawn`);
  }
  await page.screenshot({ path: join(out, "study.png"), fullPage: true });
  // The files `nmci track` writes, exported from the page: the CSVs equal to the CLI's for
  // the same study; the charts its SVGs.
  const dir = join(out, "track-cli");
  execFileSync("cargo", ["run", "--quiet", "--bin", "nmci", "--", "track", "--runs", "2", "--steps", "80", "--seed", "4", "--out", dir], { cwd: root });
  const exported = async (name) => {
    await page.selectOption("#study-export-file", name);
    const [download] = await Promise.all([page.waitForEvent("download"), page.click("#study-export")]);
    assert.equal(download.suggestedFilename(), name);
    return readFile(await download.path(), "utf8");
  };
  for (const name of ["nees.csv", "rmse.csv", "two_sigma.csv", "coin.csv"]) {
    const [mine, cli] = [await exported(name), await readFile(join(dir, name), "utf8")];
    const rowsOf = (t) => t.trim().split("\n").map((l) => l.split(","));
    const [a, b] = [rowsOf(mine), rowsOf(cli)];
    assert.deepEqual(a[0], b[0], `${name}: header`);
    assert.equal(a.length, b.length, name);
    // The same arithmetic in wasm and natively: equal to 1e-12 relative (libm may differ in
    // the last bits).
    a.slice(1).forEach((row, k) => row.forEach((v, j) => {
      const [x, y] = [Number(v), Number(b[k + 1][j])];
      assert.ok(x === y || Math.abs(x - y) <= 1e-12 * Math.max(Math.abs(x), Math.abs(y)), `${name} row ${k + 1} col ${j}: ${x} vs ${y}`);
    }));
  }
  for (const name of ["nees.svg", "coin.svg"]) {
    const [mine, cli] = [await exported(name), await readFile(join(dir, name), "utf8")];
    const size = (t) => t.match(/<svg[^>]*width="(\d+)" height="(\d+)"/).slice(1);
    assert.deepEqual(size(mine), size(cli), name);
    const labels = (t) => [...t.matchAll(/<text[^>]*>([^<]*[A-Za-z][^<]*)<\/text>/g)].map((m) => m[1]).filter((l) => !/^[\d.e+-]+$/.test(l));
    assert.deepEqual(labels(mine), labels(cli), `${name}: titles, legend and axis labels`);
  }
});

test("the study tab draws the chosen network, says whether it fits the paper's text, and runs it", async () => {
  await page.click("#tab-study");
  // The default network fits the paper's text; it is drawn with 16 agents.
  await page.waitForFunction(() => document.querySelectorAll("#study-network-svg circle").length === 16);
  assert.match(await text("#study-network-caption"), /^Fits the paper's text/);
  // The figure's reading does not: agent 7 hears of groups 3–4 only through 11.
  await page.selectOption("#study-network", "figure");
  assert.equal(await text("#study-network-caption"), "Does not fit the paper's text: no agent of groups 3–4 reaches agent 7 without passing through agent 11.");
  assert.equal(await page.locator("#study-network-svg path").count(), 16 + 3);
  // Custom links: prefilled with the default's, edited, checked as typed.
  await page.selectOption("#study-network", "custom");
  assert.equal(await page.inputValue("#study-links"), "4-7 7-10 7-11 9-16 12-13");
  await page.fill("#study-links", "4-7 7-10 7-11 9-16 12-13 3-12");
  assert.equal(await text("#study-network-caption"), "Does not fit the paper's text: agent 1 reaches agent 11 without passing through agent 7.");
  await page.fill("#study-links", "4-7 7-17");
  assert.equal(await text("#err-study"), "invalid scenario: bridge 7–17 must join two different agents among 1..=16");
  assert.equal(await page.locator("#study-links.bad").count(), 1);
  await page.fill("#study-links", "4-7 7-11 x");
  assert.equal(await text("#err-study"), 'links: write pairs of agents like "4-7 7-11" (cannot read "x")');
  await page.click("#study-start");
  assert.equal(await text("#err-study"), 'links: write pairs of agents like "4-7 7-11" (cannot read "x")');
  // The figure's reading, run: nmCI's ω on groups 3–4 is exactly 0 (it takes 11's blocks).
  await page.selectOption("#study-network", "figure");
  assert.equal(await text("#err-study"), "");
  await page.fill("#study-runs", "1");
  await page.fill("#study-steps", "20");
  await page.uncheck("#study-coin");
  await page.click("#study-start");
  await page.waitForFunction(() => document.body.dataset.study === "done", null, { timeout: 120_000 });
  assert.match(await text("#study-omega"), /nmCI 1\.00, 1\.00, 1\.00, 1\.00, 0\.00, 0\.00, 0\.00, 0\.00 \(G1x … G4y\)/);
  await page.screenshot({ path: join(out, "study-network.png"), fullPage: true });
  await page.selectOption("#study-network", "paper");
  await page.check("#study-coin");
});

test("the study tab rejects bad settings inline and can be stopped", async () => {
  await page.click("#tab-study");
  await page.fill("#study-runs", "0");
  await page.click("#study-start");
  assert.match(await text("#err-study"), /runs must be a whole number in 1…100 \(got "0"\)/);
  assert.equal(await page.locator("#study-runs.bad").count(), 1);
  await page.fill("#study-runs", "3");
  await page.fill("#study-steps", "400");
  await page.click("#study-start");
  assert.equal(await text("#err-study"), "");
  await page.waitForFunction(() => /^3 runs, step \d+ of 400/.test(document.querySelector("#study-progress").textContent), null, { timeout: 60_000 });
  await page.click("#study-stop");
  await page.waitForFunction(() => document.body.dataset.study === "stopped", null, { timeout: 60_000 });
  assert.equal(await page.locator("#study-start").isEnabled(), true);
  await page.click("#tab-explorer");
  assert.equal(await page.locator("#explorer").isVisible(), true);
});

test("a panic in the study's worker is reported inline, and the next run gets a fresh worker", async () => {
  await page.click("#tab-study");
  await page.evaluate(() => window.nmciTabs.study.panicForTest("forced by the end-to-end test"));
  await page.waitForFunction(() => document.body.dataset.study === "error", null, { timeout: 60_000 });
  assert.match(await text("#err-study"), /^the computation crashed \(panicked at src\/wasm\.rs:\d+:\d+: forced by the end-to-end test\); a fresh worker takes the next run$/);
  assert.equal(await page.locator("#study-start").isEnabled(), true);
  await page.fill("#study-runs", "1");
  await page.fill("#study-steps", "20");
  await page.click("#study-start");
  await page.waitForFunction(() => document.body.dataset.study === "done", null, { timeout: 120_000 });
  assert.equal(await text("#err-study"), "");
  assert.match(await text("#study-progress"), /^done: 1 run × 20 steps/);
});

test("the fig. 2 tab runs the sample-size study: non-conservative at N = 1, nmCI's diag(1, 1) by N = 100", async () => {
  await page.click("#tab-fig2");
  assert.equal(await page.locator("#fig2").isVisible(), true);
  await page.fill("#fig2-sizes", "1, 10, 0");
  await page.click("#fig2-start");
  assert.match(await text("#err-fig2"), /sizes must be a comma-separated list of whole numbers in 1…5000/);
  await page.fill("#fig2-runs", "30");
  await page.fill("#fig2-sizes", "1,10,100");
  await page.fill("#fig2-seed", "3");
  await page.click("#fig2-start");
  assert.equal(await text("#err-fig2"), "");
  await page.waitForFunction(() => document.body.dataset.fig2 === "done", null, { timeout: 180_000 });
  assert.match(await text("#fig2-progress"), /^30 of 30 runs/);
  const rows = await page.evaluate(() => [...document.querySelectorAll("#fig2-table tbody tr")].map((tr) => [...tr.children].map((td) => td.textContent)));
  assert.deepEqual(rows.map((r) => r[0]), ["1", "10", "100"]);
  assert.ok(Number(rows[0][2]) < 0, `N = 1: some run non-conservative (${rows[0][2]})`);
  assert.ok(Number(rows[2][1]) <= 1e-5, `N = 100: median deviation ${rows[2][1]}`);
  assert.ok(Number(rows[2][2]) >= -1e-6, `N = 100: worst ${rows[2][2]}`);
  // COIN, scale-free: the SDP's above 1 at N = 1, 1 by N = 100; nmCI's exactly 1.
  assert.ok(Number(rows[0][4]) > 1.001, `N = 1: max COIN ${rows[0][4]}`);
  assert.ok(Number(rows[2][4]) <= 1.00001, `N = 100: max COIN ${rows[2][4]}`);
  assert.ok(rows.every((r) => r[5] === "1.00000"), JSON.stringify(rows));
  assert.ok(rows.every((r) => Number(r[3]) >= -1e-9 && r[6] === "0"), JSON.stringify(rows));
  const NMCI_RGB = hexRgb((await ruleOf("nmci")).colour);
  // The charts of fig2.svg (wasm `fig2_charts` + `draw_chart`): the deviation's median over
  // the three sizes; the zero line, then the SDP's and nmCI's medians; nmCI's colour drawn.
  assert.equal(await page.getAttribute("#fig2-dev", "data-points"), "3");
  assert.equal(await page.getAttribute("#fig2-eig", "data-points"), "2,3,3");
  assert.ok((await pixelsOf("#fig2-eig", NMCI_RGB)) > 20, "nmCI's colour not drawn");
  await page.screenshot({ path: join(out, "fig2.png"), fullPage: true });
  // `nmci fig2`'s files, exported: its CSV columns and the numbers the table shows; its
  // two-panel SVG at the CLI's size.
  const dir = join(out, "fig2-cli");
  execFileSync("cargo", ["run", "--quiet", "--bin", "nmci", "--", "fig2", "--runs", "2", "--sizes", "1,10,100", "--out", dir], { cwd: root });
  const exported = async (name) => {
    await page.selectOption("#fig2-export-file", name);
    const [download] = await Promise.all([page.waitForEvent("download"), page.click("#fig2-export")]);
    return readFile(await download.path(), "utf8");
  };
  const csv = (await exported("fig2.csv")).trim().split("\n").map((l) => l.split(","));
  const cliCsv = (await readFile(join(dir, "fig2.csv"), "utf8")).trim().split("\n").map((l) => l.split(","));
  assert.deepEqual(csv[0], cliCsv[0], "the CLI's columns");
  assert.deepEqual(csv.slice(1).map((r) => r[0]), ["1", "10", "100"]);
  const column = (name) => csv[0].indexOf(name);
  csv.slice(1).forEach((r, k) => assert.equal(Number(r[column("failures")]), Number(rows[k][6])));
  const svg = await exported("fig2.svg");
  const size = (t) => t.match(/<svg[^>]*width="(\d+)" height="(\d+)"/).slice(1);
  assert.deepEqual(size(svg), size(await readFile(join(dir, "fig2.svg"), "utf8")));
  await page.click("#tab-explorer");
});

test("the N-way tab fuses three estimates: nmCI per block, CI one weight set; bad input inline", async () => {
  await page.click("#tab-nway");
  assert.equal(await page.locator("#nway").isVisible(), true);
  await page.waitForFunction(() => document.body.dataset.nway === "ready", null, { timeout: 60_000 });
  assert.equal(await page.locator("#nway-inputs tbody tr").count(), 3);
  // Fully unknown pairs: one block, nmCI = CI.
  assert.equal(await text("#nway-row-nmci .trace"), await text("#nway-row-ci .trace"));
  // Diagonal cross-covariances: two blocks, x₁ from e1 and x₂ from e2 (trace 1 + 1).
  await page.selectOption("#nway-pattern", "diagonal");
  await page.waitForFunction(() => document.querySelector("#nway-row-nmci .trace")?.textContent === "2.000");
  assert.equal(await text("#nway-row-nmci .weights"), "{x1}: [1.000, 0.000, 0.000] · {x2}: [0.000, 1.000, 0.000]");
  assert.ok((await num("#nway-row-ci .trace")) > 2);
  const ciWeights = (await text("#nway-row-ci .weights")).match(/\[(.*)\]/)[1].split(",").map(Number);
  assert.equal(ciWeights.length, 3);
  assert.ok(Math.abs(ciWeights.reduce((a, b) => a + b, 0) - 1) < 2e-3 && ciWeights.every((w) => w >= 0));
  assert.equal(await page.locator("#nway-plot path.nway-estimate").count(), 3);
  assert.equal(await page.locator("#nway-layer-nmci").count(), 1);
  await page.screenshot({ path: join(out, "nway.png"), fullPage: true });
  // A fourth estimate, then removed again.
  await page.click("#nway-add");
  assert.equal(await page.locator("#nway-inputs tbody tr").count(), 4);
  await page.waitForFunction(() => document.querySelectorAll("#nway-plot path.nway-estimate").length === 4);
  await page.locator("#nway-inputs tbody tr").nth(3).locator("button").click();
  assert.equal(await page.locator("#nway-inputs tbody tr").count(), 3);
  // Bad input: named inline, the input marked; a covariance that is not positive definite
  // gets the core's typed error.
  const p11 = page.locator('#nway-inputs input[aria-label="e1 p11"]');
  await p11.fill("abc");
  assert.equal(await text("#err-nway"), 'e1 p11: "abc" is not a number');
  assert.equal(await page.locator("#nway-inputs input.bad").count(), 1);
  await p11.fill("-1");
  await page.waitForFunction(() => /estimates\[0\]\.p/.test(document.querySelector("#err-nway").textContent));
  await p11.fill("1");
  await page.waitForFunction(() => document.querySelector("#err-nway").textContent === "" && document.body.dataset.nway === "ready");
  assert.equal(await text("#nway-row-nmci .trace"), "2.000");
  await page.click("#tab-explorer");
});

test("every tab fits a 1400 px and a phone-width window: no page-wide horizontal scroll, no table cut", async () => {
  // Every table filled: a tiny study and fig. 2 first.
  await page.click("#tab-study");
  await page.fill("#study-runs", "1");
  await page.fill("#study-steps", "10");
  await page.click("#study-start");
  await page.waitForFunction(() => document.body.dataset.study === "done", null, { timeout: 120_000 });
  await page.click("#tab-fig2");
  await page.fill("#fig2-runs", "2");
  await page.fill("#fig2-sizes", "1,10");
  await page.click("#fig2-start");
  await page.waitForFunction(() => document.body.dataset.fig2 === "done", null, { timeout: 120_000 });
  for (const [width, height] of [[1400, 900], [390, 844]]) {
    await page.setViewportSize({ width, height });
    for (const tab of ["explorer", "study", "fig2", "nway"]) {
      await page.click(`#tab-${tab}`);
      await page.waitForTimeout(200); // a resize redraws the charts in the next frame
      const [scroll, client] = await page.evaluate(() => [document.documentElement.scrollWidth, document.documentElement.clientWidth]);
      assert.ok(scroll <= client, `${tab} at ${width} px: the page scrolls sideways (${scroll} > ${client})`);
      // Whatever sticks out of the window is inside a box that scrolls itself.
      const loose = await page.evaluate(() => {
        const W = document.documentElement.clientWidth;
        const boxed = (e) => { for (let p = e.parentElement; p; p = p.parentElement) if (getComputedStyle(p).overflowX !== "visible") return true; return false; };
        return [...document.querySelectorAll("body *")].filter((e) => e.offsetParent && e.getBoundingClientRect().right > W + 1 && !boxed(e)).map((e) => `${e.tagName}#${e.id}`);
      });
      assert.deepEqual(loose, [], `${tab} at ${width} px`);
      // The charts are drawn at the canvas' width.
      for (const canvas of await page.locator(`#${tab} canvas.chart`).all()) {
        if (!(await canvas.isVisible()) || !(await canvas.getAttribute("data-points"))) continue;
        const [w, cssW] = await canvas.evaluate((c) => [c.width / devicePixelRatio, c.clientWidth]);
        assert.ok(Math.abs(w - cssW) <= 1, `${tab} at ${width} px: a chart drawn ${w} px wide in a ${cssW} px box`);
      }
      // Nothing needs its box scrolled: every table and button is whole (below 600 px each
      // row is a card of labelled values, www/tables.js).
      const cut = await page.evaluate((tab) => [...document.querySelectorAll(`#${tab} .table-scroll`)]
        .filter((b) => b.offsetParent && b.scrollWidth > b.clientWidth + 1).map((b) => b.firstElementChild.id), tab);
      assert.deepEqual(cut, [], `${tab} at ${width} px: a table cut by its box`);
      // Numbers never break inside a token: single-number cells do not wrap.
      const wrapping = await page.evaluate((tab) => [...document.querySelectorAll(`#${tab} td.trace, #${tab} td.det, #${tab} td.margin`)]
        .filter((td) => getComputedStyle(td).whiteSpace !== "nowrap").length, tab);
      assert.equal(wrapping, 0, `${tab} at ${width} px`);
      await page.screenshot({ path: join(out, `fit-${width}-${tab}.png`), fullPage: true });
    }
  }
  await page.setViewportSize({ width: 1400, height: 900 });
  await page.click("#tab-explorer");
});

test("each tab says what it shows: a 'What am I looking at?' panel whose doc links are served", async () => {
  for (const tab of ["explorer", "study", "fig2", "nway"]) {
    await page.click(`#tab-${tab}`);
    const panel = page.locator(`#explain-${tab}`);
    await panel.locator("summary").click();
    assert.ok(await panel.isVisible(), tab);
    const links = await panel.locator("a").evaluateAll((as) => as.map((a) => a.href));
    assert.ok(links.length > 0, tab);
    for (const href of links) {
      const response = await page.request.get(href);
      assert.equal(response.status(), 200, href);
      assert.match(await response.text(), /^# /, href);
    }
  }
  await page.click("#tab-explorer");
  for (const term of ["conservative", "relaxation", "bracket", "proven", "certificate level, sectors, cones", "COIN"]) {
    assert.match(await text("#explain-explorer"), new RegExp(term), term);
  }
  // The footer's timing belongs to the explorer.
  assert.ok(await page.locator("#timing").isVisible());
  await page.click("#tab-nway");
  assert.ok(!(await page.locator("#timing").isVisible()));
  // The N-way picture has a legend: each estimate, then the two rules.
  await page.waitForFunction(() => document.body.dataset.nway === "ready");
  assert.deepEqual((await page.locator("#nway-legend > span").allInnerTexts()).map((t) => t.trim()), ["e1", "e2", "e3", "N-way CI", "N-way nmCI"]);
  // The study panel says what will be drawn before the run; the network's colours are named.
  await page.click("#tab-study");
  assert.ok(await page.locator("#study-placeholder").isVisible());
  assert.equal(await page.locator("#study canvas.chart:visible").count(), 0);
  assert.match(await text("#study-network-legend"), /Red: agent 7.*blue: agent 11/);
  await page.click("#tab-explorer");
});

test("nmCI stays visible where it coincides with other bounds: drawn last, long-dashed", async () => {
  const layers = await page.locator("#plot g[clip-path] path[id^=layer-]").evaluateAll((ps) => ps.map((p) => [p.id, p.getAttribute("stroke-dasharray")]));
  assert.deepEqual(layers.at(-1), ["layer-nmci", "9 5"], JSON.stringify(layers));
});

test("after an invalid edit the old numbers are marked stale until the input is valid again", async () => {
  assert.equal(await page.evaluate(() => document.body.dataset.stale), "false");
  await cell("pa", 1, 1).fill("abc");
  await page.waitForFunction(() => document.body.dataset.stale === "true");
  assert.ok(await page.locator("#stale-note").isVisible());
  await cell("pa", 1, 1).fill("3");
  await settle();
  await page.waitForFunction(() => document.body.dataset.stale === "false");
  assert.ok(!(await page.locator("#stale-note").isVisible()));
});

test("the paper's preset at n = 4: the page's bracket is the CLI's for the same request, and the second stage closes it as sdp_cuts does", async () => {
  await page.selectOption("#dim", "4");
  await settle();
  // The second stage runs (the first bracket is open) and may finish at once: read both
  // stages from the export once it has.
  await page.waitForFunction(() => document.body.dataset.proving === "false", null, { timeout: 120_000 });
  assert.match(await text("#gap-verdict"), /^proven optimal to 10⁻⁶/);
  const [download] = await Promise.all([page.waitForEvent("download"), page.click("#export-json")]);
  const numbers = JSON.parse(await readFile(await download.path(), "utf8"));
  // The matrices the page fills in: the new states' variances 1 in both, a diagonal pattern.
  const eye4 = (d) => d.map((v, i) => d.map((_, j) => (i === j ? v : 0)));
  const request = { pa: eye4([3, 1, 1, 1]), pb: eye4([1, 4, 1, 1]), pab_unknown: eye4([1, 1, 1, 1]).map((r) => r.map(Boolean)), samples: 200, seed: 0 };
  assert.deepEqual([numbers.state.pa, numbers.state.pb], [request.pa, request.pb]);
  // The first stage's bracket is the CLI's `sdp` for the same request (to the page's six
  // digits: the SDP's KKT solver differs between wasm and native), open by 0.2 %.
  const sdp = cli({ ...request, method: "sdp" });
  const six = (v) => Number(v.toFixed(6));
  assert.deepEqual([six(numbers.gap.lower), six(numbers.gap.upper)], [six(sdp.lower_bound), six(sdp.upper_bound)]);
  assert.equal(numbers.gap.closed, false);
  // The worst case lies at correlations ±1 between the tied variances, which samples miss;
  // the cutting planes find it, in the page and in the CLI.
  assert.ok(numbers.second_stage.closed, JSON.stringify(numbers.second_stage));
  const { samples, seed, ...cuts } = request;
  assert.ok(cli({ ...cuts, method: "sdp_cuts" }).gap_closed);
  // The best proven bound is a row of the table.
  assert.equal(await page.locator("#row-proven").count(), 1);
  assert.match(await text("#row-proven"), /cutting planes, proven bound/);
});
