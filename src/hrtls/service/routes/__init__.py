"""HTTP and WebSocket routes, thin: validate, authorise, call the library, answer."""
