// Serves the repository's tools/ and a bake folder over HTTP, opens the three.js page in
// headless Chromium and prints the page's result (JSON) on stdout. Fails loudly (exit 1)
// when Chromium cannot start or the page reports an error.
// Usage: node tools/threejs/shoot.mjs BAKE_DIR vertex|lightmap WIDTH HEIGHT
import http from "node:http";
import path from "node:path";
import { readFile } from "node:fs/promises";
import { execFile } from "node:child_process";
import { fileURLToPath } from "node:url";

const [bakeDir, variant, width, height] = process.argv.slice(2);
const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), "../..");
const types = { ".html": "text/html", ".mjs": "text/javascript", ".js": "text/javascript", ".glb": "model/gltf-binary" };
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
const page = `http://127.0.0.1:${server.address().port}/tools/threejs/view.html?variant=${variant}&width=${width}&height=${height}`;
const browser = process.env.CHROMIUM ?? "chromium";
const args = ["--headless", "--no-sandbox", "--disable-gpu-sandbox", "--use-angle=swiftshader",
  "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist", "--virtual-time-budget=60000",
  "--run-all-compositor-stages-before-draw", "--dump-dom", page];
execFile(browser, args, { maxBuffer: 1 << 28, timeout: 240000 }, (error, stdout, stderr) => {
  server.close();
  const match = /<pre id="result">([\s\S]*?)<\/pre>/.exec(stdout);
  if (error && !match) {
    console.error(`Chromium (${browser}) failed to start or run: ${error.message}\n${stderr.slice(-2000)}`);
    process.exit(1);
  }
  if (!match || match[1] === "pending") {
    console.error(`the page did not finish:\n${stderr.slice(-2000)}`);
    process.exit(1);
  }
  const text = match[1].replace(/&quot;/g, '"').replace(/&amp;/g, "&");
  const result = JSON.parse(text);
  if (result.error) {
    console.error(`the page failed: ${result.error}`);
    process.exit(1);
  }
  process.stdout.write(text + "\n");
});
