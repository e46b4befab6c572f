import { useCallback, useState } from "react";

/** The page's status line (what just happened) and its error (what failed). */
export interface StatusLine {
  message: string;
  error: string | null;
  /** Say what happened; keeps the error. */
  say: (message: string) => void;
  /** Report a success: clears the error, then says what happened. */
  done: (message: string) => void;
  /** Report a failure (null clears it). */
  fail: (error: string | null) => void;
}

export function useStatusLine(): StatusLine {
  const [message, setMessage] = useState("");
  const [error, setError] = useState<string | null>(null);
  const done = useCallback((note: string) => {
    setError(null);
    setMessage(note);
  }, []);
  return { message, error, say: setMessage, done, fail: setError };
}
