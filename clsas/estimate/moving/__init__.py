"""Moving-target estimation and focusing (Kiang & Kiang 2022, sections III-VII)."""
