"""Web console: HTTP server helpers and the static page (no build step, no CDN)."""
