// Typed HTTP client for the backend, generated from frontend/openapi.json.
import createClient, { type Middleware } from "openapi-fetch";
import type { paths } from "./schema";
import { currentToken, saveSession } from "./session";

const auth: Middleware = {
  onRequest({ request }) {
    const token = currentToken();
    if (token) request.headers.set("Authorization", `Bearer ${token}`);
    return request;
  },
  onResponse({ response }) {
    if (response.status === 401 && !response.url.endsWith("/api/auth/login")) {
      saveSession(null);
      window.location.assign("/login");
    }
    return response;
  },
};

export const api = createClient<paths>({ baseUrl: "" });
api.use(auth);

/** Human-readable message from a FastAPI error body ({detail: string | [{msg, loc}]}). */
export function errorMessage(error: unknown, fallback = "Request failed"): string {
  if (error && typeof error === "object" && "detail" in error) {
    const detail = (error as { detail: unknown }).detail;
    if (typeof detail === "string") return detail;
    if (Array.isArray(detail)) {
      return detail
        .map((d: { msg?: string; loc?: unknown[] }) =>
          [d.loc?.slice(1).join("."), d.msg].filter(Boolean).join(": "),
        )
        .join("; ");
    }
  }
  return fallback;
}
