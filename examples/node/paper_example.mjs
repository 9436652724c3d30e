// The paper's 2-D example from Node, through the npm package (`scripts/wasm.sh pack`, then
// `npm install target/npm/nmci-*.tgz`): CI, nmCI with the off-diagonal of P_ab known to be
// zero, the certified rule with one known zero, and a refused request.
import { fuse, version } from "nmci";

const pa = [[3, 0], [0, 1]];
const pb = [[1, 0], [0, 4]];

const ci = fuse({ pa, pb, method: "ci" });
console.log(`nmci ${version()}`);
console.log(`CI: tr P = ${ci.trace.toFixed(3)} (ω = ${ci.omega[0].toFixed(3)}), ${ci.guarantee}`);

const nmci = fuse({ pa, pb, pab_unknown: [[true, false], [false, true]], method: "nmci" });
console.log(`nmCI: tr P = ${nmci.trace.toFixed(3)} (ω = [${nmci.omega.map((w) => w.toFixed(3)).join(", ")}])`);

const oneZero = [[true, true], [false, true]];
const certified = fuse({ pa, pb, pab_unknown: oneZero, method: "certified" });
console.log(`certified, one known zero: tr P = ${certified.trace.toFixed(10)}, ${certified.guarantee}`);

try {
  fuse({ pa, pb: [[1]], method: "ci" });
} catch (e) {
  console.log(`refused (field ${e.field}): ${e.message}`);
}
