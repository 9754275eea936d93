"""The speed-accuracy report (report.sh runs each section as `python3 -m report.SECTION` with scripts/ on the path)."""
