"""The browser interface: static files served by the lab service."""
