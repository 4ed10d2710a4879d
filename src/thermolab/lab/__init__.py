"""The lab service: access control, storage and the HTTP/WebSocket API."""
