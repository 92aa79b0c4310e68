-- Run by tests/integration/test_vplus_neovim.py in `nvim --headless --clean`: opens $VPLUS_FILE, starts the
-- language server $VPLUS_CMD (a JSON list) with Neovim's own LSP client, waits for the file's diagnostics, asks
-- for the definition at $VPLUS_LINE:$VPLUS_COL (0-based) and writes both as JSON to $VPLUS_OUT, then quits.
local file, out = os.getenv("VPLUS_FILE"), os.getenv("VPLUS_OUT")
local function finish(result)
  local f = assert(io.open(out, "w"))
  f:write(vim.fn.json_encode(result))
  f:close()
  vim.cmd("qa!")
end
local ok, err = pcall(function()
  vim.cmd("edit " .. vim.fn.fnameescape(file))
  local buf = vim.api.nvim_get_current_buf()
  vim.bo[buf].filetype = "vplus"
  local config = { name = "aioadept-vplus", cmd = vim.fn.json_decode(os.getenv("VPLUS_CMD")),
                   root_dir = vim.fn.fnamemodify(file, ":p:h") }
  local client_id
  if vim.lsp.start then          -- Neovim 0.8 and later
    client_id = vim.lsp.start(config)
  else                           -- 0.7 (Debian 12's neovim)
    client_id = vim.lsp.start_client(config)
    vim.lsp.buf_attach_client(buf, client_id)
  end
  local got = vim.wait(30000, function() return #vim.diagnostic.get(buf) > 0 end, 50)
  local diagnostics = {}
  for _, d in ipairs(vim.diagnostic.get(buf)) do
    table.insert(diagnostics, { lnum = d.lnum, col = d.col, end_col = d.end_col, message = d.message,
                                severity = d.severity, source = d.source })
  end
  local params = { textDocument = { uri = vim.uri_from_bufnr(buf) },
                   position = { line = tonumber(os.getenv("VPLUS_LINE")),
                                character = tonumber(os.getenv("VPLUS_COL")) } }
  local definition = {}
  for _, r in pairs(vim.lsp.buf_request_sync(buf, "textDocument/definition", params, 30000) or {}) do
    table.insert(definition, r.result or vim.NIL)
  end
  finish({ version = vim.version(), waited = got, client = client_id, diagnostics = diagnostics,
           definition = definition })
end)
if not ok then finish({ error = tostring(err) }) end
