// scripts/run.sh with its port taken: one line on stderr naming the port and `PORT=`, exit 1,
// before any build (README: `scripts/run.sh`).
import { test } from "node:test";
import assert from "node:assert/strict";
import { createServer } from "node:net";
import { spawnSync } from "node:child_process";
import { fileURLToPath } from "node:url";

const root = fileURLToPath(new URL("../..", import.meta.url));

test("a taken port is said in one line naming PORT=, before any build", async () => {
  const server = createServer();
  await new Promise((ok) => server.listen(0, "127.0.0.1", ok));
  const { port } = server.address();
  try {
    const run = spawnSync("bash", ["scripts/run.sh"], { cwd: root, env: { ...process.env, PORT: String(port) }, encoding: "utf8" });
    assert.equal(run.status, 1, run.stderr);
    assert.equal(run.stdout, "", "nothing ran before the check (setup prints on stdout)");
    assert.equal(run.stderr.trim(), `scripts/run.sh: port ${port} on 127.0.0.1 is taken (another server?); choose another: PORT=${port + 1} scripts/run.sh`);
  } finally {
    server.close();
  }
});
