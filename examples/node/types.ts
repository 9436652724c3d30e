// Compiled (not run) by the package test with `tsc --noEmit --strict`: the package's types
// describe the contract, so a misspelt method or a field of the wrong type does not compile.
import { explore, fuse, prove, rules, type Exploration, type FuseRequest, type FuseResponse, type Guarantee } from "nmci";

const request: FuseRequest = {
  pa: [[3, 0], [0, 1]],
  pb: [[1, 0], [0, 4]],
  pab_unknown: [[true, false], [false, true]],
  method: "nmci",
};
const response: FuseResponse = fuse(request);
const trace: number = response.trace;
const omega: number[] | undefined = response.omega;
const closed: boolean | undefined = fuse({ ...request, method: "sdp_cuts" }).gap_closed;
const both: FuseResponse[] = fuse([request, { ...request, method: "ci" }]);
console.log(trace, omega, closed, both.length, rules());

// The rest of the API is typed too.
const guarantee: Guarantee = rules()[0].guarantee;
const analysis: Exploration = explore({ pa: request.pa, pb: request.pb, pab_unknown: request.pab_unknown });
const lower: number | undefined = analysis.gap?.lower;
const proven: number | undefined = prove({ pa: request.pa, pb: request.pb })?.rule?.trace;
console.log(guarantee, lower, proven);
// @ts-expect-error: explore takes no method (every rule runs)
explore({ pa: [[1]], pb: [[1]], method: "ci" });

// @ts-expect-error: not a rule of the contract
fuse({ pa: [[1]], pb: [[1]], method: "volume" });
// @ts-expect-error: `samples` is a number
fuse({ pa: [[1]], pb: [[1]], method: "sdp", samples: "many" });
