// Bundles the page (src/main.js with React 17 and Foxglove Studio's own
// `@foxglove/studio-base`) into dist/. The studio bundle loads its panels'
// chunks, fonts and WebAssembly next to the script that loaded it, so its
// assets are copied beside app.js; the repository's layouts go to
// dist/layouts/.
import { build } from "esbuild";
import { copyFileSync, mkdirSync, readdirSync, rmSync } from "node:fs";
import { join } from "node:path";

const out = "dist";
const assets = "node_modules/@foxglove/studio-base/assets";
const layouts = "../../deploy/foxglove";

rmSync(out, { recursive: true, force: true });
mkdirSync(out, { recursive: true });
for (const name of readdirSync(assets)) {
  // index.js is the studio's entry, bundled into app.js itself.
  if (name !== "index.js") {
    copyFileSync(join(assets, name), join(out, name));
  }
}
copyFileSync("index.html", join(out, "index.html"));
// The shipped layouts, so that dist/ served alone opens on them.
mkdirSync(join(out, "layouts"));
for (const name of readdirSync(layouts)) {
  if (name.endsWith(".json")) {
    copyFileSync(join(layouts, name), join(out, "layouts", name));
  }
}
await build({
  entryPoints: ["src/main.js"],
  bundle: true,
  outfile: join(out, "app.js"),
  format: "iife",
  platform: "browser",
  target: "chrome100",
  define: { "process.env.NODE_ENV": '"production"' },
  logLevel: "warning",
});
