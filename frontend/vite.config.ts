/// <reference types="vitest/config" />
import react from "@vitejs/plugin-react";
import { defineConfig } from "vite";

const backend = process.env.VIGIL_BACKEND ?? "127.0.0.1:8000";

export default defineConfig({
  base: "/",
  plugins: [react()],
  server: {
    port: 5620,
    proxy: {
      "/api": { target: `http://${backend}`, changeOrigin: true },
      "/ws": { target: `ws://${backend}`, ws: true },
    },
  },
  build: { outDir: "dist", emptyOutDir: true },
  test: { include: ["src/**/*.test.ts"], environment: "node" },
});
