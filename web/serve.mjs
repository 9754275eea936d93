// A static file server for the viewer on the loopback interface: web/ at /, a directory of envprefilter outputs at
// /data/. Usage: node web/serve.mjs DATA_DIR [PORT]  (PORT 0 or absent: a free port; the URL is printed).
// Also imported by tests/js/viewer_capture.mjs.
import { createReadStream, statSync } from 'node:fs';
import { createServer } from 'node:http';
import { extname, join, normalize, resolve, sep } from 'node:path';
import { fileURLToPath } from 'node:url';

const TYPES = {
  '.html': 'text/html; charset=utf-8',
  '.js': 'text/javascript; charset=utf-8',
  '.mjs': 'text/javascript; charset=utf-8',
  '.json': 'application/json',
  '.png': 'image/png',
};

export const webRoot = resolve(fileURLToPath(new URL('.', import.meta.url)));

// The file under `root` that `urlPath` names, or null when it would leave root.
function under(root, urlPath) {
  const path = normalize(join(root, decodeURIComponent(urlPath)));
  return path === root || path.startsWith(root + sep) ? path : null;
}

/** Starts the server; resolves to { server, url } once it listens on 127.0.0.1. */
export function serve(dataDir, port = 0, root = webRoot) {
  const data = resolve(dataDir);
  const server = createServer((req, res) => {
    const urlPath = new URL(req.url, 'http://127.0.0.1').pathname;
    const file = urlPath.startsWith('/data/')
      ? under(data, urlPath.slice('/data/'.length))
      : under(root, urlPath === '/' ? 'index.html' : urlPath);
    let size = -1;
    try {
      if (file) {
        const st = statSync(file);
        if (st.isFile()) size = st.size;
      }
    } catch {
      size = -1;
    }
    if (size < 0) {
      res.writeHead(404, { 'Content-Type': 'text/plain' });
      res.end(`not found: ${urlPath}\n`);
      return;
    }
    res.writeHead(200, {
      'Content-Type': TYPES[extname(file)] ?? 'application/octet-stream',
      'Content-Length': size,
      'Cache-Control': 'no-store',
    });
    createReadStream(file).pipe(res);
  });
  return new Promise((ok, fail) => {
    server.once('error', fail);
    server.listen(port, '127.0.0.1', () => ok({ server, url: `http://127.0.0.1:${server.address().port}/` }));
  });
}

if (process.argv[1] && resolve(process.argv[1]) === fileURLToPath(import.meta.url)) {
  if (process.argv.length < 3) {
    console.error('usage: node serve.mjs DATA_DIR [PORT]');
    process.exit(2);
  }
  const { url } = await serve(process.argv[2], Number(process.argv[3] ?? 0));
  console.log(`envkit viewer: ${url}  (files of ${process.argv[2]} under ${url}data/; Ctrl-C stops)`);
}
