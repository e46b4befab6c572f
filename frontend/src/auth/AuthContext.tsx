import { createContext, useCallback, useContext, useMemo, useState, type ReactNode } from "react";
import { api, errorMessage } from "../api/client";
import { loadSession, saveSession, type Session } from "../api/session";
import type { User } from "../api/types";

interface AuthValue {
  user: User | null;
  token: string | null;
  login(username: string, password: string): Promise<User>;
  logout(): void;
}

const AuthContext = createContext<AuthValue | null>(null);

export function AuthProvider({ children }: { children: ReactNode }) {
  const [session, setSession] = useState<Session | null>(loadSession);

  const login = useCallback(async (username: string, password: string) => {
    const { data, error } = await api.POST("/api/auth/login", { body: { username, password } });
    if (!data) throw new Error(errorMessage(error, "Sign-in failed"));
    const next = { token: data.access_token, user: data.user };
    saveSession(next);
    setSession(next);
    return data.user;
  }, []);

  const logout = useCallback(() => {
    // Revoke the session on the server too (its token would otherwise stay valid until it
    // expires); the local session is cleared at once, whatever the answer.
    const token = loadSession()?.token;
    saveSession(null);
    setSession(null);
    if (token) {
      void api
        .POST("/api/auth/logout", { headers: { Authorization: `Bearer ${token}` } })
        .catch(() => undefined);
    }
  }, []);

  const value = useMemo(
    () => ({ user: session?.user ?? null, token: session?.token ?? null, login, logout }),
    [session, login, logout],
  );
  return <AuthContext.Provider value={value}>{children}</AuthContext.Provider>;
}

export function useAuth(): AuthValue {
  const value = useContext(AuthContext);
  if (!value) throw new Error("useAuth outside AuthProvider");
  return value;
}
