// Tokenizes files with a TextMate grammar in VS Code's engine; prints one JSON object:
// {file: [{tokens: [[start, end, [scopes...]], ...], depth: <rule stack depth at the line's end>}, ...]}.
// Usage: node tokenize.mjs GRAMMAR.json SCOPE FILE...
import fs from "node:fs";
import { createRequire } from "node:module";
import vsctm from "vscode-textmate";
import oniguruma from "vscode-oniguruma";

const require = createRequire(import.meta.url);
const [grammarPath, scopeName, ...files] = process.argv.slice(2);
const wasm = fs.readFileSync(require.resolve("vscode-oniguruma/release/onig.wasm"));
await oniguruma.loadWASM(wasm.buffer.slice(wasm.byteOffset, wasm.byteOffset + wasm.byteLength));
const registry = new vsctm.Registry({
  onigLib: Promise.resolve({
    createOnigScanner: (patterns) => new oniguruma.OnigScanner(patterns),
    createOnigString: (s) => new oniguruma.OnigString(s),
  }),
  loadGrammar: async (scope) =>
    scope === scopeName ? vsctm.parseRawGrammar(fs.readFileSync(grammarPath, "utf8"), grammarPath) : null,
});
const grammar = await registry.loadGrammar(scopeName);
if (!grammar) throw new Error(`no grammar ${scopeName} in ${grammarPath}`);
const out = {};
for (const file of files) {
  // V+ files are Latin-1 (Adept DeskTop); CR LF or LF
  const lines = fs.readFileSync(file, "latin1").split(/\r\n|\r|\n/);
  let stack = vsctm.INITIAL;
  out[file] = lines.map((line) => {
    const r = grammar.tokenizeLine(line, stack);
    stack = r.ruleStack;
    return { tokens: r.tokens.map((t) => [t.startIndex, t.endIndex, t.scopes]), depth: stack.depth };
  });
}
process.stdout.write(JSON.stringify(out));
