// Narrow windows (≤ 600 px, style.css): each table row is shown as a card of "header: value"
// lines, so no column is cut. The labels come from the table's own header: every body cell
// gets `data-label`, kept current as the pages refill their tables.
function label(table) {
  const heads = [...table.querySelectorAll("thead th")].map((th) => th.textContent.replace(/\s+/g, " ").trim());
  for (const tr of table.querySelectorAll("tbody tr")) {
    [...tr.children].forEach((td, i) => {
      if (heads[i] && td.dataset.label !== heads[i]) td.dataset.label = heads[i];
    });
  }
}

/** Labels every table of the page now and whenever its body changes. */
export function watchTables() {
  for (const table of document.querySelectorAll("table")) {
    label(table);
    new MutationObserver(() => label(table)).observe(table.tBodies[0] ?? table, { childList: true, subtree: true });
  }
}
