// Browser benchmark of the tracking study (not a test: nothing is asserted on time):
// `node tests/e2e/bench-study.mjs [repeats]` serves the page, runs ONE default run
// (400 steps, all five estimators) in the Study tab's Web Worker in headless Chromium, and
// prints the wall time of each repeat: `study/one_run` without the exact COIN (the run
// itself), `study/three_runs` (the page's default of 3 runs, which advance together: their
// shared covariances once per step), then `study/one_run_coin` with the COIN (the run beside
// the five exact error propagations, in a second worker). Needs www/pkg (scripts/wasm.sh build).
import { serveWww, launchChromium } from "./harness.mjs";

const repeats = Number(process.argv[2] ?? 3);
const server = await serveWww();
const chromium = await launchChromium();
const { page } = chromium;
try {
  await page.goto(server.base);
  await page.click("#tab-study");
  await page.fill("#study-steps", "400");
  await page.fill("#study-seed", "1");
  for (const [id, runs, coin] of [["study/one_run", 1, false], ["study/three_runs", 3, false], ["study/one_run_coin", 1, true]]) {
    await page.fill("#study-runs", String(runs));
    await page.setChecked("#study-coin", coin);
    const seconds = [];
    for (let r = 0; r < repeats; r++) {
      await page.click("#study-start");
      await page.waitForFunction(() => document.body.dataset.study === "done", null, { timeout: 600_000 });
      const text = await page.locator("#study-progress").innerText();
      const match = /in ([\d.]+) s/.exec(text);
      seconds.push(Number(match[1]));
      console.log(`${id} (headless Chromium, wasm): ${match[1]} s — ${text}`);
    }
    seconds.sort((a, b) => a - b);
    console.log(`${id} (headless Chromium, wasm): min ${seconds[0]} s, median ${seconds[Math.floor(seconds.length / 2)]} s over ${seconds.length} repeats`);
  }
} finally {
  await chromium.close();
  server.close();
}
