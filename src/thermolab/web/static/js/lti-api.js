// @ts-check
// The LTI tool's API calls (lab/http/routers/lti_admin.py), beside api.js's.

import { request } from "./api.js";

const enc = encodeURIComponent;

export const ltiApi = {
  tool: () => request("GET", "/api/lti/tool"),
  platforms: () => request("GET", "/api/lti/platforms"),
  register: (spec) => request("POST", "/api/lti/platforms", spec),
  removePlatform: (id) => request("DELETE", `/api/lti/platforms/${enc(id)}`),
  rotateKey: () => request("POST", "/api/lti/keys/rotate"),
  syncRoster: (course) => request("POST", `/api/lti/courses/${enc(course)}/roster`),
  grades: () => request("GET", "/api/lti/grades"),
  retryGrade: (id) => request("POST", `/api/lti/grades/${enc(id)}/retry`),
  deepLink: (key) => request("GET", `/api/lti/deep-links/${enc(key)}`),
};
