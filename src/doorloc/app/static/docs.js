// The API documentation page: Swagger UI (bundled, static/vendor/swagger-ui) on this service's /openapi.json.
// A file of its own, not an inline script, so the page runs under a CSP that allows same-origin scripts only.
"use strict";

window.addEventListener("load", () => {
  window.ui = SwaggerUIBundle({
    url: "/openapi.json",
    dom_id: "#swagger-ui",
    validatorUrl: null, // the public validator badge would be a request to another site
    deepLinking: true,
  });
});
