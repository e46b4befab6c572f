// The signed-in user's token and profile, kept in sessionStorage so a reload stays signed in.
import type { User } from "./types";

const KEY = "vigil.session";

export interface Session {
  token: string;
  user: User;
}

export function loadSession(): Session | null {
  const raw = sessionStorage.getItem(KEY);
  if (!raw) return null;
  try {
    return JSON.parse(raw) as Session;
  } catch {
    sessionStorage.removeItem(KEY);
    return null;
  }
}

export function saveSession(session: Session | null): void {
  if (session) sessionStorage.setItem(KEY, JSON.stringify(session));
  else sessionStorage.removeItem(KEY);
}

export function currentToken(): string | null {
  return loadSession()?.token ?? null;
}
