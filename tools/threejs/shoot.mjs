// Serves the repository's tools/ and a bake folder over HTTP, opens the three.js page in
// headless Chromium (puppeteer-core driving the system's `chromium`, or $CHROMIUM) and prints
// the page's result (JSON) on stdout. Fails loudly (exit 1) when Chromium cannot start or the
// page reports an error.
// Usage: node tools/threejs/shoot.mjs BAKE_DIR vertex|lightmap WIDTH HEIGHT (view.html)
//        node tools/threejs/shoot.mjs BAKE_DIR ktx2 (ktx2.html: the specular cube's texels)
import http from "node:http";
import path from "node:path";
import { readFile } from "node:fs/promises";
import { fileURLToPath } from "node:url";
import puppeteer from "puppeteer-core";

const [bakeDir, variant, width, height] = process.argv.slice(2);
const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), "../..");
const types = { ".html": "text/html", ".mjs": "text/javascript", ".js": "text/javascript", ".glb": "model/gltf-binary", ".wasm": "application/wasm" };
const server = http.createServer(async (req, res) => {
  const url = new URL(req.url, "http://localhost");
  const file = url.pathname.startsWith("/bake/")
    ? path.join(path.resolve(bakeDir), url.pathname.slice(6))
    : path.join(root, url.pathname);
  try {
    const body = await readFile(file);
    res.writeHead(200, { "content-type": types[path.extname(file)] ?? "application/octet-stream" });
    res.end(body);
  } catch {
    res.writeHead(404);
    res.end();
  }
});
await new Promise((resolve) => server.listen(0, "127.0.0.1", resolve));
const page = `http://127.0.0.1:${server.address().port}/tools/threejs/${variant === "ktx2" ? "ktx2" : "view"}.html?variant=${variant}&width=${width}&height=${height}`;
const executablePath = process.env.CHROMIUM ?? "/usr/bin/chromium";
let browser;
try {
  browser = await puppeteer.launch({
    executablePath,
    headless: true,
    args: ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist"],
  });
} catch (error) {
  console.error(`Chromium (${executablePath}) failed to start: ${error.message}`);
  process.exit(1);
}
try {
  const tab = await browser.newPage();
  const logs = [];
  tab.on("console", (m) => logs.push(m.text()));
  tab.on("pageerror", (e) => logs.push(String(e)));
  await tab.goto(page);
  await tab.waitForFunction(() => document.getElementById("result").textContent !== "pending", { timeout: 240000 });
  const text = await tab.$eval("#result", (e) => e.textContent);
  const result = JSON.parse(text);
  if (result.error) throw new Error(`the page failed: ${result.error}\n${logs.join("\n")}`);
  process.stdout.write(text + "\n");
} catch (error) {
  console.error(String(error.message ?? error));
  process.exitCode = 1;
} finally {
  await browser.close();
  server.close();
}
