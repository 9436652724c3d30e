// Work per message of the study's workers, about 0.1–0.2 s each.
//
// The run workers (www/study-worker.js and www/study-rules-worker.js) must cut the steps at
// the same places: the first takes the second's steps up to where its own are. Every run
// advances by each step (their shared covariances once, then each run's means), so many runs
// take fewer steps per message.
export const chunk = (runs) => Math.max(1, Math.round(200 / Math.max(10, runs)));

// Estimator-steps per message of the exact COIN's workers (www/study-coin-worker.js and
// www/study-coin-part-worker.js).
export const COIN_CHUNK = 10;
