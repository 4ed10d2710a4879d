// ESLint (flat config) for the browser code: the recommended rules plus a few
// that keep the modules plain and safe. The vendored uPlot is not ours to lint.
import js from "@eslint/js";
import globals from "globals";

export default [
  { ignores: ["src/thermolab/web/static/vendor/**", "node_modules/**", "**/.venv/**"] },
  js.configs.recommended,
  {
    files: ["src/thermolab/web/static/js/**/*.js"],
    languageOptions: {
      ecmaVersion: 2022,
      sourceType: "module",
      globals: { ...globals.browser },
    },
    rules: {
      "no-shadow": "error",
      "no-var": "error",
      "prefer-const": "error",
      eqeqeq: ["error", "always"],
      "no-unused-vars": ["error", { argsIgnorePattern: "^_", ignoreRestSiblings: true }],
      "no-restricted-properties": [
        "error",
        { property: "innerHTML", message: "Put text in with textContent (dom.h / setText): server text must not become markup." },
      ],
    },
  },
];
