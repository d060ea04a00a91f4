// Runs the Khronos glTF-Validator on each GLB named on the command line and prints one JSON line
// per file: {"file", "errors", "warnings", "infos", "messages": [the errors and warnings, at most 20]}.
// Used by tests/real_clients/gltf_validator.rs.
import { readFile } from 'node:fs/promises';
import validator from 'gltf-validator';

for (const file of process.argv.slice(2)) {
  const bytes = new Uint8Array(await readFile(file));
  const report = await validator.validateBytes(bytes, { maxIssues: 1000 });
  const messages = report.issues.messages
    .filter((m) => m.severity <= 1)
    .slice(0, 20)
    .map((m) => `${m.severity === 0 ? 'error' : 'warning'} ${m.code} at ${m.pointer}: ${m.message}`);
  console.log(JSON.stringify({
    file,
    errors: report.issues.numErrors,
    warnings: report.issues.numWarnings,
    infos: report.issues.numInfos,
    messages,
  }));
}
