"""The evaluation's results as typed records, their verdicts, and the reports written from them (Markdown, HTML,
figures)."""
