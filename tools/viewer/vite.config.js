// SPDX-License-Identifier: Apache-2.0
// Builds the viewer page (web/index.html) and the story page (web/story.html) into
// dist/, which is committed and compiled into the toonforce binary (cmake/embed_assets.cmake).
// Deterministic for the locked versions (package-lock.json): .ci/run rebuilds and compares with
// the committed dist/ (scripts/check-dist.mjs).
import { defineConfig } from 'vite';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const web = path.join(path.dirname(fileURLToPath(import.meta.url)), 'web');

export default defineConfig({
  root: 'web',
  base: '/',
  logLevel: 'warn',
  build: {
    outDir: '../dist',
    emptyOutDir: true,
    assetsInlineLimit: 0,
    chunkSizeWarningLimit: 2000,
    reportCompressedSize: false,
    sourcemap: false,
    target: 'es2022',
    rollupOptions: {
      input: { index: path.join(web, 'index.html'), story: path.join(web, 'story.html') },
    },
  },
});
