// Browser benchmark of the explorer's analysis (not a test: nothing is asserted on time):
// `node tests/e2e/bench-explore.mjs [calls]` serves the page and, in a fresh page of headless
// Chromium, calls the wasm `explore` on the page's two-block preset (n = 4, the page's request:
// 200 SDP samples, 300 region samples, sampler "auto") `calls` times in a row on the main
// thread, printing each call's time. The first calls run V8's baseline compilation of the
// module's functions, later ones its optimized code. The end-to-end interaction test's edits at
// n = 4 (test-output/e2e/interaction-n4.json) come after the page's other tests, with optimized
// code, but each with the edit's own work in the browser (input handling, layout, paint)
// running beside the analysis, which calls in a row do not have (docs/development.md).
// Then the page's second stage (`prove`) on a three-state state. Needs www/pkg
// (scripts/wasm.sh build).
import { serveWww, launchChromium } from "./harness.mjs";

const calls = Number(process.argv[2] ?? 30);
const server = await serveWww();
const chromium = await launchChromium();
try {
  const { page } = chromium;
  await page.goto(server.base);
  const times = await page.evaluate(async (calls) => {
    const m = await import("./pkg/nmci.js");
    await m.default();
    const [t, f] = [true, false];
    const request = {
      pa: [[3, 0.5, 0, 0], [0.5, 1, 0, 0], [0, 0, 1, 0.2], [0, 0, 0.2, 2]],
      pb: [[1, -0.3, 0, 0], [-0.3, 2, 0, 0], [0, 0, 4, 1], [0, 0, 1, 2]],
      pab_unknown: [[t, t, f, f], [t, t, f, f], [f, f, t, t], [f, f, t, t]],
      samples: 200, region_samples: 300, sampler: "auto", seed: 0, criterion: "trace", max_trials: 200_000,
    };
    const out = [];
    for (let i = 0; i < calls; i++) {
      const t0 = performance.now();
      m.explore(request);
      out.push(performance.now() - t0);
    }
    return out;
  }, calls);
  console.log(`explore/twoblock (headless Chromium, wasm, main thread), ms per call in order: ${times.map((x) => x.toFixed(0)).join(", ")}`);
  const later = times.slice(10).sort((a, b) => a - b);
  if (later.length) console.log(`explore/twoblock (n = 4, the page's request; headless Chromium, wasm, main thread), calls 11…${calls}: min ${later[0].toFixed(1)} ms, median ${later[Math.floor(later.length / 2)].toFixed(1)} ms`);
  // The second stage (wasm `prove`) on the end-to-end test's three-state state, whose first
  // bracket is open by 10 %: three calls after the explore calls above (optimized code).
  const proofs = await page.evaluate(async () => {
    const m = await import("./pkg/nmci.js");
    const [t, f] = [true, false];
    const request = {
      pa: [[2.573, 1.484, 0.916], [1.484, 1.767, 0.987], [0.916, 0.987, 3.586]],
      pb: [[2.645, -0.105, 1.613], [-0.105, 4.357, -0.592], [1.613, -0.592, 1.562]],
      pab_unknown: [[t, t, f], [t, f, t], [f, t, t]],
      samples: 200, region_samples: 300, sampler: "auto", seed: 0, criterion: "trace", max_trials: 200_000, time_limit: 30,
    };
    const out = [];
    for (let i = 0; i < 3; i++) {
      const t0 = performance.now();
      const p = m.prove(request);
      out.push({ ms: performance.now() - t0, relative: p.relative, own: p.own_rule_proven });
    }
    return out;
  });
  const sorted = proofs.map((p) => p.ms).sort((a, b) => a - b);
  console.log(`prove/anti-diagonal (n = 3, the page's second stage; headless Chromium, wasm, main thread), 3 calls: min ${sorted[0].toFixed(0)} ms, median ${sorted[1].toFixed(0)} ms (gap ${proofs[0].relative.toExponential(1)}, own rule proven: ${proofs[0].own})`);
} finally {
  await chromium.close();
  server.close();
}
