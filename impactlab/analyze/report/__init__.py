"""The report: findings chosen by thresholds on the numbers (`findings`), the sentences that
answer the handout (`headline`, `answers`, `handout`), report.md (`markdown`) and
report.html (`html`), figures and their cache."""
