// @ts-check
/**
 * The LTI deep-linking answer posts itself back to the LMS (the page's one form).
 * The server renders the form (lab/http/lti_pages.py); this only submits it.
 */
const form = document.getElementById("lti-return");
if (form instanceof HTMLFormElement) form.submit();
