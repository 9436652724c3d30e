// Steps per message of the study's run workers (www/study-worker.js and
// www/study-rules-worker.js, which must cut the steps at the same places: the first takes the
// second's steps up to where its own are): about 0.1–0.2 s of work. Every run advances by
// each step (their shared covariances once, then each run's means), so many runs take fewer
// steps per message.
export const chunk = (runs) => Math.max(1, Math.round(200 / Math.max(10, runs)));
