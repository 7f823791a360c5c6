// Validates glTF files with the Khronos glTF-Validator and prints one JSON report per file
// (a JSON array), resources (images, buffers) resolved beside each file.
// Usage: node tools/validate_gltf.mjs FILE...
import { readFile } from "node:fs/promises";
import path from "node:path";
import validator from "gltf-validator";

const reports = [];
for (const file of process.argv.slice(2)) {
  const data = new Uint8Array(await readFile(file));
  const report = await validator.validateBytes(data, {
    uri: path.basename(file),
    maxIssues: 200,
    externalResourceFunction: (uri) =>
      readFile(path.join(path.dirname(file), decodeURIComponent(uri))).then((b) => new Uint8Array(b)),
  });
  reports.push(report);
}
process.stdout.write(JSON.stringify(reports, null, 1) + "\n");
