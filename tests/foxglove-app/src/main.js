// Foxglove Studio's own app, opened on a Foxglove WebSocket server.
//
// The page's address says what to open, in the app's own deep-link form
// plus one parameter of this page:
//   index.html?ds=foxglove-websocket&ds.url=ws://127.0.0.1:8765&layoutId=lab
// `layoutId` names a layout file served at layouts/<layoutId>.json (the
// repository's deploy/foxglove/<site>.json); the app starts on it.
// Nothing is stored between visits: settings and layouts live in memory.
import React from "react";
import ReactDOM from "react-dom";
import {
  App,
  FoxgloveWebSocketDataSourceFactory,
  initI18n,
  waitForFonts,
} from "@foxglove/studio-base";

/** The app's settings, in memory. */
class MemoryConfiguration {
  constructor() {
    this.values = new Map();
    this.listeners = new Map();
  }
  get(key) {
    return this.values.get(key);
  }
  async set(key, value) {
    this.values.set(key, value);
    for (const cb of this.listeners.get(key) ?? []) {
      cb(value);
    }
  }
  addChangeListener(key, cb) {
    if (!this.listeners.has(key)) {
      this.listeners.set(key, new Set());
    }
    this.listeners.get(key).add(cb);
  }
  removeChangeListener(key, cb) {
    this.listeners.get(key)?.delete(cb);
  }
}

/** The app's layout storage, in memory, holding the layouts given. */
class MemoryLayouts {
  constructor(layouts) {
    this.layouts = new Map(layouts.map((l) => [l.id, l]));
  }
  async list() {
    return [...this.layouts.values()];
  }
  async get(_namespace, id) {
    return this.layouts.get(id);
  }
  async put(_namespace, layout) {
    this.layouts.set(layout.id, layout);
    return layout;
  }
  async delete(_namespace, id) {
    this.layouts.delete(id);
  }
  async importLayouts() {}
}

/** The layout named by `layoutId`, as the app stores one; none without it. */
async function layouts(params) {
  const id = params.get("layoutId");
  if (!id) {
    return [];
  }
  const answer = await fetch(`layouts/${encodeURIComponent(id)}.json`);
  if (!answer.ok) {
    throw new Error(`layout ${id}: HTTP ${answer.status}`);
  }
  const data = await answer.json();
  return [
    {
      id,
      name: id,
      permission: "CREATOR_WRITE",
      baseline: { data, savedAt: undefined },
      working: undefined,
      syncInfo: undefined,
    },
  ];
}

async function main() {
  const params = new URL(window.location.href).searchParams;
  await waitForFonts();
  await initI18n();
  const app = React.createElement(App, {
    deepLinks: [window.location.href],
    appConfiguration: new MemoryConfiguration(),
    dataSources: [new FoxgloveWebSocketDataSourceFactory()],
    layoutStorage: new MemoryLayouts(await layouts(params)),
    extensionLoaders: [],
    enableGlobalCss: true,
  });
  ReactDOM.render(app, document.getElementById("root"));
  // For a test driving the page: the app has been handed to React.
  window.ickonAppStarted = true;
}

main().catch((error) => {
  console.error(error);
  document.getElementById("root").textContent = `The app did not start: ${error}`;
});
