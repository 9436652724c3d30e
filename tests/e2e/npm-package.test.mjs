// The npm package (`scripts/wasm.sh pack`) as a user gets it: the tarball installed into an
// empty folder, the Node example run from there, its TypeScript types compiled against a typed
// example, and the types' field lists compared with the Rust crate's.
import { test } from "node:test";
import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import { copyFileSync, mkdtempSync, readdirSync, readFileSync, rmSync, writeFileSync } from "node:fs";
import { tmpdir } from "node:os";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";

const root = join(dirname(fileURLToPath(import.meta.url)), "..", "..");
const packed = join(root, "target", "npm");

function install() {
  const tarballs = readdirSync(packed).filter((f) => /^nmci-.*\.tgz$/.test(f));
  assert.equal(tarballs.length, 1, "run `scripts/wasm.sh pack` first (scripts/test.sh does)");
  const dir = mkdtempSync(join(tmpdir(), "nmci-npm-"));
  writeFileSync(join(dir, "package.json"), JSON.stringify({ name: "user", private: true, type: "module" }));
  // A local tarball with no dependencies: nothing is fetched.
  execFileSync("npm", ["install", "--offline", "--no-audit", "--no-fund", "--loglevel=error", join(packed, tarballs[0])], { cwd: dir });
  return dir;
}

const dir = install();
process.on("exit", () => rmSync(dir, { recursive: true, force: true }));
const node = (args) => execFileSync(process.execPath, args, { cwd: dir, encoding: "utf8" });

test("the installed package carries both licence texts", () => {
  for (const name of ["LICENSE-MIT", "LICENSE-APACHE"]) {
    const text = readFileSync(join(dir, "node_modules", "nmci", name), "utf8");
    assert.equal(text, readFileSync(join(root, name), "utf8"), name);
  }
});

test("the Node example runs from the installed package with the README's numbers", () => {
  copyFileSync(join(root, "examples", "node", "paper_example.mjs"), join(dir, "paper_example.mjs"));
  const out = node(["paper_example.mjs"]);
  assert.match(out, /^CI: tr P = 3\.088 \(ω = 0\.556\), conservative$/m);
  assert.match(out, /^nmCI: tr P = 2\.000 \(ω = \[/m);
  assert.match(out, /^certified, one known zero: tr P = 2\.0000000933, conservative$/m);
  assert.match(out, /^refused \(field pb\): /m);
});

test("a list of requests gives the list of responses, and a bad one is named", () => {
  const script = `
    import { fuse } from "nmci";
    const pa = [[3, 0], [0, 1]], pb = [[1, 0], [0, 4]];
    const [ci, nm] = fuse([{ pa, pb, method: "ci" }, { pa, pb, pab_unknown: [[true, false], [false, true]], method: "nmci" }]);
    let field;
    try { fuse([{ pa, pb, method: "ci" }, { pa: [[-1]], pb: [[1]], method: "ci" }]); } catch (e) { field = e.field; }
    console.log(JSON.stringify({ ci: ci.trace, nm: nm.trace, field }));`;
  const got = JSON.parse(node(["--input-type=module", "-e", script]));
  assert.equal(got.nm, 2);
  assert.ok(Math.abs(got.ci - 3.088) < 1e-3);
  assert.equal(got.field, "[1].pa");
});

/** The property names of `interface name { … }` in a declaration file. */
function declared(text, name) {
  const body = text.match(new RegExp(`export interface ${name}(?: extends [^{]+)? \\{([\\s\\S]*?)\\n\\}`))[1];
  return [...body.matchAll(/^  (\w+)\??:/gm)].map((m) => m[1]).sort();
}

test("the types declare exactly the contract's fields, as the Rust crate lists them", () => {
  const fields = JSON.parse(node(["--input-type=module", "-e", 'import { contract_fields } from "nmci"; console.log(JSON.stringify(contract_fields()))']));
  const types = readFileSync(join(dir, "node_modules", "nmci", "contract.d.ts"), "utf8");
  assert.deepEqual(declared(types, "FuseRequest"), [...fields.request].sort());
  assert.deepEqual(declared(types, "FuseResponse"), [...fields.response].sort());
});

test("the API's other functions are typed as they answer, and the page's exports and test hooks are not declared", () => {
  const script = `
    import { rules, explore, prove, version } from "nmci";
    const state = { pa: [[3, 0, 0], [0, 1, 0], [0, 0, 2]], pb: [[1, 0, 0], [0, 4, 0], [0, 0, 1]],
                    pab_unknown: [[true, true, false], [true, true, true], [false, true, true]], region_samples: 20 };
    const a = explore(state), p = prove(state);
    console.log(JSON.stringify({ rule: Object.keys(rules()[0]), exploration: Object.keys(a), gap: Object.keys(a.gap),
      report: Object.keys(a.rules[0]), proof: p ? Object.keys(p) : null, version: version() }));`;
  const got = JSON.parse(node(["--input-type=module", "-e", script]));
  const types = readFileSync(join(dir, "node_modules", "nmci", "index.d.ts"), "utf8");
  assert.deepEqual(declared(types, "RuleInfo"), [...got.rule].sort());
  const subset = (keys, ...names) => keys.forEach((k) => assert.ok(names.some((n) => declared(types, n).includes(k)), `${names[0]}.${k} is not declared`));
  subset(got.exploration, "Exploration");
  subset(got.gap, "Gap");
  subset(got.report, "RuleReport");
  assert.ok(got.proof, "the three-state state's first bracket is open, so prove() answers");
  subset(got.proof, "Proof", "Gap");
  assert.match(got.version, /^\d+\.\d+\.\d+/);
  const generated = readFileSync(join(dir, "node_modules", "nmci", "nmci.d.ts"), "utf8");
  // Declared as functions or classes (the module's raw wasm exports stay listed in `InitOutput`).
  const declaredApi = [...`${generated}\n${types}`.matchAll(/^export (?:declare )?(?:function|class) (\w+)/gm)].map((m) => m[1]);
  for (const hidden of ["panic_for_test", "install_panic_hook", "Study", "StudyCoin", "fig2_run", "draw_chart"]) {
    assert.ok(!declaredApi.includes(hidden), hidden);
  }
  assert.deepEqual([...new Set(declaredApi)].sort(), ["contract_fields", "explore", "fuse", "initSync", "prove", "rules", "version"]);
});

test("the types compile against a typed example, and reject a wrong method and a wrong type", () => {
  copyFileSync(join(root, "examples", "node", "types.ts"), join(dir, "types.ts"));
  const tsc = join(root, "tests", "e2e", "node_modules", "typescript", "bin", "tsc");
  // `@ts-expect-error` lines fail the compile if the error they expect is not there, so
  // types loose enough to take any request would fail this test too.
  // `esnext`: wasm-bindgen's declarations use `Symbol.dispose` (the package README says so).
  const args = [tsc, "--noEmit", "--strict", "--target", "esnext", "--module", "nodenext", "--moduleResolution", "nodenext", "types.ts"];
  try {
    execFileSync(process.execPath, args, { cwd: dir, encoding: "utf8" });
  } catch (e) {
    assert.fail(`tsc: ${e.stdout}${e.stderr}`);
  }
});
