// @ts-check
// The rig's guide, beside the panel the student is using: a "Guide" button on
// each panel opens a drawer at that panel's steps (panel-1 … panel-4), with
// the other sections (introduction, theory, school) one click away. The text
// comes from GET /api/rigs/{rig}/guide in the interface's language: Markdown
// rendered and sanitised on the server (nh3), maths as MathML, so nothing a
// teacher writes can run here. A section not written in the reader's language
// comes in English, and says so.
//
// Teachers also get an editor: the section's Markdown in a textarea, a preview
// (the server's rendering), Save (a new revision), and the list of revisions
// (who, when) with View and Restore. "Insert picture" uploads a file (checked
// and cleaned by the server) and puts its Markdown, ![alt](/api/guide-images/N),
// at the textarea's cursor.

import { request } from "../api.js";
import { h, replaceChildren, setText, when } from "../dom.js";
import { glossaryList } from "../glossary.js";
import { language, t } from "../i18n.js";

/** The guide's sections in reading order, with the key of each one's name. */
const SECTION_NAMES = {
  introduction: "guide.introduction",
  theory: "guide.theory",
  "panel-1": "guide.panel-1",
  "panel-2": "guide.panel-2",
  "panel-3": "guide.panel-3",
  "panel-4": "guide.panel-4",
  school: "guide.school",
};

/** Which guide section belongs to each identification panel (panels/definitions.js ids). */
export const PANEL_SECTIONS = { "srm-lsm": "panel-1", malsm: "panel-2", wlsm: "panel-3" };

const enc = encodeURIComponent;
const guideApi = {
  read: (rig, lang) => request("GET", `/api/rigs/${enc(rig)}/guide?lang=${enc(lang)}`),
  save: (rig, lang, section, markdown) =>
    request("PUT", `/api/rigs/${enc(rig)}/guide/${enc(section)}?lang=${enc(lang)}`, { markdown }),
  revisions: (rig, lang, section) =>
    request("GET", `/api/rigs/${enc(rig)}/guide/${enc(section)}/revisions?lang=${enc(lang)}`),
  revision: (rig, id) => request("GET", `/api/rigs/${enc(rig)}/guide-revisions/${enc(id)}`),
  restore: (rig, id) => request("POST", `/api/rigs/${enc(rig)}/guide-revisions/${enc(id)}/restore`),
  preview: (markdown) => request("POST", "/api/guide-preview", { markdown }),
  /** @param {string} rig @param {File} file @param {string} alt */
  uploadImage: (rig, file, alt) => {
    const form = new FormData();
    form.append("file", file);
    form.append("alt", alt);
    return request("POST", `/api/rigs/${enc(rig)}/guide-images`, undefined, { form });
  },
};

/** The picture types the lab takes (the server checks them again with Pillow). */
const IMAGE_ACCEPT = "image/png,image/jpeg,image/gif,image/webp";

/**
 * Put the server's sanitised HTML in an element. It is parsed into an inert
 * document (no script runs there) and its nodes moved in: the server's nh3 pass
 * already removed scripts, event handlers and unsafe URLs.
 * @param {HTMLElement} el
 * @param {string} html
 */
function showHtml(el, html) {
  const doc = new DOMParser().parseFromString(`<body>${html}</body>`, "text/html");
  el.replaceChildren(...Array.from(doc.body.childNodes));
}

export class GuideDrawer {
  /**
   * @param {HTMLElement} parent
   * @param {string} rigId
   * @param {{username: string, role: string} | null} user
   */
  constructor(parent, rigId, user) {
    this.rigId = rigId;
    this.teacher = user?.role === "teacher";
    /** @type {Record<string, any>} the sections as last read, by name */
    this.sections = {};
    this.current = "introduction";
    /** @type {string | null} the section the article shows */
    this.shown = null;
    this.lang = "";
    /** @type {Promise<void> | null} the read under way */
    this.loading = null;
    this.nav = h("nav", { class: "guide-nav", "aria-label": t("guide.sections") });
    this.buttons = {};
    for (const [section, key] of Object.entries(SECTION_NAMES)) {
      const button = h("button", { type: "button", class: "link-button", "data-section": section,
        onclick: () => this.show(section) }, t(key));
      this.buttons[section] = button;
      this.nav.append(button);
    }
    this.note = h("p", { class: "muted small", "data-testid": "guide-note", hidden: true });
    this.meta = h("p", { class: "muted small", "data-testid": "guide-meta" });
    this.article = h("article", { class: "guide-text", "data-testid": "guide-text", tabindex: "-1" });
    this.status = h("p", { role: "status", class: "small" });
    this.editor = this.teacher ? this._buildEditor() : null;
    this.closeButton = h("button", { type: "button", onclick: () => this.close() }, t("guide.close"));
    this.el = h(
      "aside",
      { class: "card guide-drawer", "aria-labelledby": "guide-heading", "data-testid": "guide", hidden: true },
      h("div", { class: "guide-head" }, h("h2", { id: "guide-heading" }, t("guide.heading")), this.closeButton),
      this.nav,
      this.note,
      this.article,
      this.meta,
      glossaryList(),
      this.editor ? this.editor.el : null,
      this.status,
    );
    parent.append(this.el);
  }

  /** A "Guide" button that opens this drawer at a section. */
  button(section) {
    return h("button", { type: "button", class: "guide-open", "data-guide": section,
      onclick: () => void this.open(section) }, t("guide.open"));
  }

  /** Open the drawer at a section, reading the guide in the interface's language. */
  async open(section) {
    this.el.hidden = false;
    this.current = section;
    if (this.lang !== language()) await this.load();
    this.show(section);
    this.article.focus();
  }

  close() {
    this.el.hidden = true;
  }

  /** Read the guide in the interface's language (one read at a time: callers share it). */
  load() {
    this.loading ??= this._read().finally(() => {
      this.loading = null;
    });
    return this.loading;
  }

  async _read() {
    try {
      const guide = await guideApi.read(this.rigId, language());
      this.lang = guide.lang;
      this.sections = Object.fromEntries(guide.sections.map((s) => [s.section, s]));
      setText(this.status, "");
    } catch (err) {
      setText(this.status, err.message);
    }
  }

  /** Show a section; the editor closes when the section changes (not when the same one is redrawn). */
  show(section) {
    const moved = section !== this.shown;
    this.current = section;
    for (const [name, button] of Object.entries(this.buttons)) {
      if (name === section) button.setAttribute("aria-current", "true");
      else button.removeAttribute("aria-current");
    }
    const found = this.sections[section];
    if (!found) return;
    this.shown = section;
    showHtml(this.article, found.html);
    this.article.lang = found.lang;
    this.note.hidden = found.lang === this.lang;
    setText(this.note, t("guide.fallback"));
    setText(this.meta, found.revisionId === null ? t("guide.default")
      : t("guide.savedBy", { author: found.author, time: when(found.savedAt) }));
    if (this.editor && moved) this._closeEditor();
  }

  _buildEditor() {
    const textarea = h("textarea", { rows: "14", class: "guide-source", "data-testid": "guide-source",
      "aria-label": t("guide.source") });
    const preview = h("div", { class: "guide-text guide-preview", "data-testid": "guide-preview" });
    const revisions = h("ul", { class: "guide-revisions", "data-testid": "guide-revisions" });
    const imageFile = h("input", { type: "file", accept: IMAGE_ACCEPT, "data-testid": "guide-image-file" });
    const imageAlt = h("input", { type: "text", maxlength: "200", "data-testid": "guide-image-alt" });
    const form = h("div", { class: "guide-editor", hidden: true },
      textarea,
      h("div", { class: "buttons" },
        h("button", { type: "button", onclick: () => void this._preview() }, t("guide.preview")),
        h("button", { type: "button", class: "primary", onclick: () => void this._save() }, t("guide.save")),
        h("button", { type: "button", onclick: () => this._closeEditor() }, t("guide.cancel")),
      ),
      h("div", { class: "guide-image" },
        h("label", { class: "field" }, t("guide.imageFile"), " ", imageFile),
        h("label", { class: "field" }, t("guide.imageAlt"), " ", imageAlt),
        h("button", { type: "button", "data-testid": "guide-image-insert",
          onclick: () => void this._insertImage() }, t("guide.imageInsert")),
      ),
      h("h3", null, t("guide.previewHeading")),
      preview,
      h("h3", null, t("guide.revisions")),
      revisions,
    );
    const editButton = h("button", { type: "button", "data-testid": "guide-edit",
      onclick: () => void this._openEditor() }, t("guide.edit"));
    return { el: h("div", null, editButton, form), form, textarea, preview, revisions, editButton,
      imageFile, imageAlt };
  }

  /** Upload the chosen picture and put its Markdown at the cursor (the server's message on a refusal). */
  async _insertImage() {
    const ed = this.editor;
    if (!ed) return;
    const file = ed.imageFile.files?.[0];
    if (!file) {
      setText(this.status, t("guide.imageChoose"));
      ed.imageFile.focus();
      return;
    }
    try {
      const image = await guideApi.uploadImage(this.rigId, file, ed.imageAlt.value.trim());
      const area = ed.textarea;
      const start = area.selectionStart ?? area.value.length;
      const end = area.selectionEnd ?? start;
      area.setRangeText(image.markdown, start, end, "end");
      ed.imageFile.value = "";
      ed.imageAlt.value = "";
      setText(this.status, t("guide.imageInserted"));
      area.focus();
    } catch (err) {
      setText(this.status, err.message);
    }
  }

  async _openEditor() {
    const ed = this.editor;
    if (!ed) return;
    // Edit clicked while the guide is still being read: wait for it (its
    // language names the revisions asked for; its text fills the editor).
    if (this.loading) await this.loading;
    else if (!this.lang) await this.load();
    if (!this.lang) return; // the guide could not be read: the status says why
    const found = this.sections[this.current];
    ed.textarea.value = found ? found.markdown : "";
    ed.form.hidden = false;
    ed.editButton.hidden = true;
    replaceChildren(ed.preview);
    await this._listRevisions();
    ed.textarea.focus();
  }

  _closeEditor() {
    if (!this.editor) return;
    this.editor.form.hidden = true;
    this.editor.editButton.hidden = false;
  }

  async _preview() {
    if (!this.editor) return;
    try {
      const answer = await guideApi.preview(this.editor.textarea.value);
      showHtml(this.editor.preview, answer.html);
    } catch (err) {
      setText(this.status, err.message);
    }
  }

  async _save() {
    if (!this.editor) return;
    try {
      await guideApi.save(this.rigId, this.lang, this.current, this.editor.textarea.value);
      setText(this.status, t("guide.saved"));
      await this.load();
      this.show(this.current);
      this._closeEditor();
    } catch (err) {
      setText(this.status, err.message);
    }
  }

  async _listRevisions() {
    const ed = this.editor;
    if (!ed) return;
    try {
      const rows = await guideApi.revisions(this.rigId, this.lang, this.current);
      replaceChildren(ed.revisions, rows.length ? rows.map((r) => h("li", null,
        t("guide.savedBy", { author: r.author, time: when(r.savedAt) }), " ",
        h("button", { type: "button", class: "link-button", onclick: () => void this._view(r.id) }, t("guide.view")),
        h("button", { type: "button", class: "link-button", onclick: () => void this._restore(r.id) }, t("guide.restore")),
      )) : h("li", null, t("guide.noRevisions")));
    } catch (err) {
      setText(this.status, err.message);
    }
  }

  async _view(id) {
    if (!this.editor) return;
    try {
      const revision = await guideApi.revision(this.rigId, id);
      showHtml(this.editor.preview, revision.html);
      this.editor.textarea.value = revision.markdown;
    } catch (err) {
      setText(this.status, err.message);
    }
  }

  async _restore(id) {
    try {
      await guideApi.restore(this.rigId, id);
      setText(this.status, t("guide.restored"));
      await this.load();
      this.show(this.current);
      this._closeEditor();
    } catch (err) {
      setText(this.status, err.message);
    }
  }
}

