// Fails when the built wasm package imports anything from the "env" module: on wasm32 a
// missing native symbol (BLAS, libc) turns into such an import instead of a link error, and
// the page would then fail at instantiation.
import { readFileSync, readdirSync } from "node:fs";
import { join } from "node:path";

const dir = process.argv[2] ?? "www/pkg";
const files = readdirSync(dir);
const wasmFile = files.find((f) => f.endsWith("_bg.wasm"));
const jsFile = files.find((f) => f.endsWith(".js") && !f.endsWith("_bg.js"));
if (!wasmFile || !jsFile) {
  console.error(`check-env-imports: no wasm-bindgen package in ${dir}`);
  process.exit(1);
}
const mod = new WebAssembly.Module(readFileSync(join(dir, wasmFile)));
const envImports = WebAssembly.Module.imports(mod).filter((i) => i.module === "env");
const js = readFileSync(join(dir, jsFile), "utf8");
const jsEnv = /from\s+['"]env['"]|import\(\s*['"]env['"]\s*\)/.test(js);
if (envImports.length > 0 || jsEnv) {
  console.error(
    `check-env-imports: ${join(dir, wasmFile)} imports from "env": ` +
      envImports.map((i) => i.name).join(", "),
  );
  process.exit(1);
}
console.log(`check-env-imports: ${jsFile} and ${wasmFile} import nothing from "env"`);
